"""The registries of fpsi_jax.cases: every scene records its keywords, every validation case
names its scene, and ``fpsi run --plot`` draws with the scene's own plot and observer."""
import inspect
import math

import pytest

from fpsi_jax import cases, cli
from fpsi_jax.cases import registry
from fpsi_jax.cases.plotting import default_plot


def test_every_validation_case_has_a_description_and_a_scene():
    assert cases.CASES
    for name in cases.CASES:
        assert cases.DESCRIPTIONS[name].strip(), name
        assert cases.SCENE_OF[name] in cases.SCENES, name


def test_every_scene_has_a_user_docstring():
    for name, fn in cases.SCENES.items():
        doc = fn.__doc__ or ""
        assert doc.strip(), name
        for word in ("issue ", "today"):
            assert word not in doc.lower(), (name, word)


@pytest.mark.parametrize("name", list(cases.SCENES))
def test_builder_kwargs_hold_every_keyword_of_the_call(name):
    """The @scene decorator records each keyword, default or given, in signature order."""
    sc = cases.build(name)
    assert list(sc.builder_kwargs)[:len(cases.builder_keys(name))] == cases.builder_keys(name)
    assert sc.name == name


def test_builder_kwargs_record_resolved_defaults_and_given_values():
    sc = cases.build("dam_break", dx=0.02, mu=1e-3)
    kw = sc.builder_kwargs
    assert kw["dx"] == 0.02 and kw["mu"] == 1e-3
    assert kw["h0"] == 1.25 * 0.02 and kw["dx_boundary"] == 0.02            # resolved
    assert kw["c0"] == 10 * math.sqrt(2 * 9.81 * kw["column_height"])
    sc = cases.build("collision", beta=0.3)
    assert sc.builder_kwargs["beta"] == 0.3
    assert sc.builder_kwargs["gap"] == 0.2 * sc.builder_kwargs["radius"]


def test_gate_failure_is_the_gate_with_weak_bonds():
    sig = inspect.signature(cases.get("gate_failure")).parameters
    assert list(sig) == cases.builder_keys("elastic_gate")
    assert sig["sigma_c"].default == 2.0e5 and sig["t_end"].default == 0.3
    coarse = dict(dx=0.007, d=0.005, dx_boundary=0.005, h0=0.00875)
    a = cases.build("elastic_gate", **coarse).builder_kwargs
    b = cases.build("gate_failure", **coarse).builder_kwargs
    assert list(a) == list(b)
    assert {k for k in a if a[k] != b[k]} == {"sigma_c", "tau_c", "t_end"}


def test_hooks_are_registered_for_their_scenes():
    from fpsi_jax.cases.dam_break import run_plot as dam_plot
    from fpsi_jax.cases.elastic_gate import run_plot as gate_plot, tip_observer
    assert cases.PLOTS["dam_break"] is dam_plot
    assert cases.PLOTS["elastic_gate"] is cases.PLOTS["gate_failure"] is gate_plot
    assert cases.OBSERVERS["elastic_gate"] is tip_observer
    assert set(cases.PLOTS) <= set(cases.SCENES) and set(cases.OBSERVERS) <= set(cases.SCENES)


def test_run_plot_uses_the_scenes_plot_and_observer(tmp_path, monkeypatch, capsys):
    calls = []

    def observer(scene):
        return lambda s: s.solid.x[0, 0]

    def plot(scene, res, png):
        calls.append((scene.name, png, res.observations))
        default_plot(scene, res, png)
        return [f"drew {scene.name}", "figure of merit 1.0"]

    monkeypatch.setitem(registry.OBSERVERS, "collision", observer)
    monkeypatch.setitem(registry.PLOTS, "collision", plot)
    out = tmp_path / "c.h5"
    assert cli.main(["run", "collision", "--out", str(out), "--plot", "--quiet"]) == 0
    (name, png, obs), = calls
    assert name == "collision" and png == str(tmp_path / "c.png")
    assert obs is not None and obs.shape[0] > 10              # the observer ran every step
    text = capsys.readouterr().out.splitlines()
    assert text[-2:] == ["drew collision", "figure of merit 1.0"]
    assert (tmp_path / "c.png").exists()
