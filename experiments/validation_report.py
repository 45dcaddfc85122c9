"""Write docs/validation.md from the records of ``fpsi validate --json FILE``.

    fpsi validate --json experiments/results/validate_full.json
    python experiments/validation_report.py                     # -> docs/validation.md
    python experiments/validation_report.py other.json --out /tmp/validation.md

The JSON is a list of records, one per measured quantity, each with the keys ``case``,
``quantity``, ``value``, ``reference``, ``rel_error``, ``tolerance``, ``passed``,
``wall_s`` and ``params`` (the builder's parameters and the run's figures). The page has a
summary table, then one section per case: its description, how it ran, a table of its
quantities, its parameters and the plots in experiments/results/ whose file name starts
with the case name.

A case's description is the record's ``description`` when the JSON has one; otherwise it
is read from the source of ``fpsi_jax`` (the string the case is registered with), without
importing it. Only the standard library is used, so the page can be rebuilt on a machine
without JAX.
"""
from __future__ import annotations

import argparse
import ast
import json
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_JSON = os.path.join(ROOT, "experiments", "results", "validate_full.json")
DEFAULT_OUT = os.path.join(ROOT, "docs", "validation.md")
DEFAULT_PLOTS = os.path.join(ROOT, "experiments", "results")
DEFAULT_SOURCE = os.path.join(ROOT, "fpsi_jax")
REGENERATE = ("fpsi validate --json experiments/results/validate_full.json && "
              "python experiments/validation_report.py")
# keys of ``params`` shown in the "ran" line of a case (when present), in this order
RUN_KEYS = (("n_particles", "particles"), ("steps", "steps"),
            ("dem_substeps", "DEM sub-steps per step"), ("dx", "fluid spacing dx [m]"),
            ("d", "disc diameter d [m]"))


def passed(record) -> bool:
    """The record's verdict; older files hold it as the string 'True' / 'False'."""
    p = record.get("passed")
    if isinstance(p, str):
        return p.strip().lower() in ("true", "1", "yes", "pass", "passed")
    return bool(p)


def signed_error(record):
    """The record's relative error with its sign: some cases store |error|; where
    (value − reference)/reference has the same magnitude, that signed figure is shown.
    Against a zero reference the error is the value itself, with its sign (a load −0.84 %
    short reads −0.84 %); norms (L1, RMS) are shown as recorded."""
    rel, v, ref = record.get("rel_error"), record.get("value"), record.get("reference")
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (rel, v, ref)):
        return rel
    if ref == 0 and math.isfinite(v) and abs(abs(v) - abs(rel)) <= 1e-9 * max(1e-12, abs(v)):
        return v
    if ref == 0 or not math.isfinite(v) or not math.isfinite(ref):
        return rel
    s = (v - ref) / ref
    return s if abs(abs(s) - abs(rel)) <= 1e-6 * max(1e-12, abs(s)) else rel


def fmt(x, digits=5) -> str:
    """A number for a table cell: 5 significant digits, '—' for missing."""
    if x is None:
        return "—"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        if isinstance(x, float) and not math.isfinite(x):
            return str(x)
        if x == 0:
            return "0"
        if 1e3 <= abs(x) < 1e9:        # no exponent for moderate magnitudes: 1000037
            digits = max(digits, int(math.log10(abs(x))) + 1)
        return f"{x:.{digits}g}"
    return str(x)


def pct(x) -> str:
    return "—" if x is None else f"{100.0 * float(x):+.3g} %"


def cell(text) -> str:
    """Escape what would break a Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def load_records(path):
    with open(path, encoding="utf-8") as fh:
        data = json.load(fh)
    if isinstance(data, dict):               # tolerate {"records": [...]}
        data = data.get("records", [])
    if not isinstance(data, list):
        sys.exit(f"{path}: expected a list of records")
    return [r for r in data if isinstance(r, dict) and "case" in r]


def group(records):
    """Records by case, in the order the cases first appear."""
    out = {}
    for r in records:
        out.setdefault(r["case"], []).append(r)
    return out


def _string(node):
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _func_name(node) -> str:
    f = node.func
    if isinstance(f, ast.Name):
        return f.id
    if isinstance(f, ast.Attribute):
        return f.attr
    return ""


def registered_descriptions(source_dir, names):
    """{case: description} from decorators such as ``@register("case", "description")``
    in the Python files under ``source_dir``. Decorators whose name mentions validation
    win over other registrations of the same name (a scene and its validation case may
    share a name)."""
    found = {}                                   # name -> (score, description)
    if not os.path.isdir(source_dir):
        return {}
    for dirpath, _, files in os.walk(source_dir):
        for fn in sorted(files):
            if not fn.endswith(".py"):
                continue
            try:
                with open(os.path.join(dirpath, fn), encoding="utf-8") as fh:
                    tree = ast.parse(fh.read())
            except (OSError, SyntaxError, ValueError):
                continue
            for node in ast.walk(tree):
                decos = getattr(node, "decorator_list", None)
                if not decos:
                    continue
                for d in decos:
                    if not isinstance(d, ast.Call) or not d.args:
                        continue
                    name = _string(d.args[0])
                    if name not in names:
                        continue
                    desc = _string(d.args[1]) if len(d.args) > 1 else None
                    for kw in d.keywords:
                        if kw.arg in ("description", "desc", "what"):
                            desc = _string(kw.value) or desc
                    if not desc:
                        continue
                    fname = _func_name(d).lower()
                    score = 2 if "valid" in fname else 1 if ("register" in fname
                                                               or "case" in fname) else 0
                    if name not in found or score > found[name][0]:
                        found[name] = (score, desc)
    return {k: v[1] for k, v in found.items()}


def plots_by_case(plot_dir, names):
    """{case: [png file names]}: a plot belongs to the longest case name that its stem
    equals or starts with followed by '_'."""
    out = {n: [] for n in names}
    if not os.path.isdir(plot_dir):
        return out
    for fn in sorted(os.listdir(plot_dir)):
        if not fn.lower().endswith(".png"):
            continue
        stem = fn[:-4]
        hits = [n for n in names if stem == n or stem.startswith(n + "_")]
        if hits:
            out[max(hits, key=len)].append(fn)
    return out


def _same(recs, key):
    """The value of params[key] when every record has the same one, else None."""
    vals = [json.dumps((r.get("params") or {}).get(key), sort_keys=True, default=str)
            for r in recs]
    return (recs[0].get("params") or {}).get(key) if len(set(vals)) == 1 else None


def _value_cell(v) -> str:
    return cell(json.dumps(v) if isinstance(v, (list, dict)) else fmt(v, 6))


def case_section(name, recs, description, plots, plot_link):
    lines = [f"## {name}", ""]
    if description:
        lines += [description[0].upper() + description[1:] + ".", ""]
    quick = _same(recs, "quick")
    ran = [] if quick is None else ["quick (coarse) version" if quick else "full version"]
    ran += [f"{label} {fmt(_same(recs, k))}" for k, label in RUN_KEYS
            if _same(recs, k) is not None]
    walls = sorted({round(float(r["wall_s"]), 1) for r in recs
                    if isinstance(r.get("wall_s"), (int, float))})
    if walls:
        ran.append("wall time " + " / ".join(f"{w:g}" for w in walls) + " s")
    if ran:
        lines += ["Ran as: " + ", ".join(ran) + ".", ""]
    lines += ["| quantity | value | reference | error | tolerance | passed |",
              "|---|---:|---:|---:|---:|:---:|"]
    for r in recs:
        lines.append("| " + " | ".join([
            cell(r.get("quantity", "")), fmt(r.get("value")), fmt(r.get("reference")),
            pct(signed_error(r)), pct(r.get("tolerance")).lstrip("+"),
            "✔" if passed(r) else "✘"]) + " |")
    lines.append("")
    keys = []
    for r in recs:
        keys += [k for k in (r.get("params") or {}) if k not in keys]
    common = [k for k in keys if _same(recs, k) is not None
              or all(k not in (r.get("params") or {}) for r in recs[1:])]
    varying = [k for k in keys if k not in common]
    if keys:
        lines += ["<details><summary>parameters and run figures</summary>", ""]
        if common:
            lines += ["| key | value |", "|---|---|"]
            lines += [f"| {cell(k)} | {_value_cell((recs[0].get('params') or {}).get(k))} |"
                      for k in common]
            lines.append("")
        if varying:
            lines += ["| quantity | " + " | ".join(cell(k) for k in varying) + " |",
                      "|---|" + "---|" * len(varying)]
            for r in recs:
                p = r.get("params") or {}
                lines.append(f"| {cell(r.get('quantity', ''))} | "
                             + " | ".join(_value_cell(p.get(k)) for k in varying) + " |")
            lines.append("")
        lines += ["</details>", ""]
    for fn in plots:
        lines += [f"![{fn}]({plot_link}/{fn})", "", f"*{fn}*", ""]
    return lines


def render(records, json_path, out_path, plot_dir, source_dir):
    cases = group(records)
    names = list(cases)
    desc = registered_descriptions(source_dir, set(names))
    for n, recs in cases.items():
        for r in recs:
            if r.get("description"):
                desc[n] = r["description"]
    plots = plots_by_case(plot_dir, names)
    out_dir = os.path.dirname(os.path.abspath(out_path))
    plot_link = os.path.relpath(os.path.abspath(plot_dir), out_dir).replace(os.sep, "/")
    src = os.path.relpath(os.path.abspath(json_path), ROOT).replace(os.sep, "/")
    n_ok = sum(passed(r) for r in records)
    lines = [
        "# Validation",
        "",
        "<!-- generated file: edit experiments/validation_report.py, not this page -->",
        "",
        f"This page is generated by `experiments/validation_report.py` from `{src}`, the "
        "records written by `fpsi validate --json`. Regenerate it with",
        "",
        "```bash",
        REGENERATE,
        "```",
        "",
        "Each case builds its scene at the resolution given in its parameters, runs it and "
        "compares one or more quantities with a reference: an analytic solution computed "
        "from the same parameters, or published data shipped in `fpsi_jax/data/` (sources "
        "in `fpsi_jax/data/README.md`). *error* is the relative error the case computes: "
        "(value − reference)/reference, signed, for most quantities; a norm over a whole field or "
        "curve (L1, RMS) where the quantity names one; the value itself, in the scale the "
        "quantity names, where the reference is 0; the time error over the reference time "
        "for a time of peak. A quantity passes when |error| ≤ tolerance. "
        "`fpsi validate --quick` runs the "
        "coarse versions the test suite uses, `fpsi validate CASE --set key=value` a "
        "variant of your own (analytic references follow the parameters).",
        "",
        f"{len(names)} cases, {len(records)} quantities, {n_ok} within tolerance.",
        "",
        "| case | quantities | within tolerance | largest \\|error\\| / tolerance | wall s |",
        "|---|---:|---:|---:|---:|",
    ]
    for n, recs in cases.items():
        ratios = [abs(float(r["rel_error"])) / float(r["tolerance"]) for r in recs
                  if isinstance(r.get("rel_error"), (int, float))
                  and isinstance(r.get("tolerance"), (int, float)) and r["tolerance"]]
        walls = [float(r["wall_s"]) for r in recs if isinstance(r.get("wall_s"), (int, float))]
        lines.append(f"| [{n}](#{n}) | {len(recs)} | "
                     f"{sum(passed(r) for r in recs)} | "
                     f"{fmt(max(ratios), 3) if ratios else '—'} | "
                     f"{fmt(max(walls), 3) if walls else '—'} |")
    lines.append("")
    for n, recs in cases.items():
        lines += case_section(n, recs, desc.get(n), plots.get(n, []), plot_link)
    return "\n".join(lines).rstrip() + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json", nargs="?", default=DEFAULT_JSON,
                    help="records of `fpsi validate --json` (default: %(default)s)")
    ap.add_argument("--out", default=DEFAULT_OUT, help="Markdown page (default: %(default)s)")
    ap.add_argument("--plots", default=DEFAULT_PLOTS,
                    help="folder of the case plots (default: %(default)s)")
    ap.add_argument("--source", default=DEFAULT_SOURCE,
                    help="package source read for the case descriptions (default: %(default)s)")
    args = ap.parse_args(argv)
    records = load_records(args.json)
    if not records:
        sys.exit(f"{args.json}: no records")
    text = render(records, args.json, args.out, args.plots, args.source)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w", encoding="utf-8") as fh:
        fh.write(text)
    print(f"wrote {args.out} ({len(group(records))} cases, {len(records)} quantities)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
