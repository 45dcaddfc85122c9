"""Cantilever (K6.3.3) tip deflection and first frequency at three disc sizes.

The strip is built with its clamp column on x = 0 and its tip column on x = L = 79.375 mm
whatever d is (columns L/⌊L/d⌋ apart). References: Euler–Bernoulli δ = PL³/(3EI) and
f1 = (1.875²/2π)√(EI/(ρAL⁴)); the Timoshenko shear part PL/(κGA) (κ = 5/6) of the
deflection is reported beside it.

    .venv/bin/python experiments/cantilever_span.py [--d 0.0025 0.00125 0.000625]

writes experiments/results/cantilever_span.csv
"""
from __future__ import annotations

import argparse

from fpsi_jax.cases.cantilever import cantilever_case, cantilever_frequency_case

from _table import write_rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--d", type=float, nargs="+", default=[0.0025, 0.00125, 0.000625])
    ap.add_argument("--out", default="experiments/results/cantilever_span.csv")
    a = ap.parse_args()
    rows = []
    for d in a.d:
        (tip,) = cantilever_case(False, {"d": d})
        (freq,) = cantilever_frequency_case(False, {"d": d})
        p = tip.params
        row = dict(d_mm=d * 1e3, n_discs=p["n_discs"], span_mm=p["as_built_span"] * 1e3,
                   tip_mm=tip.value * 1e3, tip_eb_mm=tip.reference * 1e3,
                   tip_error_eb=(tip.value - tip.reference) / tip.reference,
                   tip_error_with_shear=p["error_vs_reference_with_shear"],
                   settle_last_10pct=p["last_10pct_change"], f1_hz=freq.value,
                   f1_eb_hz=freq.reference,
                   f1_error=(freq.value - freq.reference) / freq.reference,
                   periods=freq.params["periods"], wall_s=tip.wall_s + freq.wall_s)
        rows.append(row)
        print(", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in row.items()), flush=True)
    write_rows(a.out, rows)


if __name__ == "__main__":
    main()
