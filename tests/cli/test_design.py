"""`quadrs tune` and `quadrs linearize` on the command line."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

import quadrs
from quadrs.cli.main import main

opt_module = importlib.import_module("quadrs.design.optimize")

SHORT = [
    "--set", "initial.position=[0.0,0.0,2.0]",
    "--set", "initial.attitude=[0.0,0.0,0.0]",
    "--set", "trajectory.waypoints=[[0.0,0.0,0.0,2.0,0.0],[2.0,0.0,0.0,2.0,0.0]]",
    "--set", 'phases=[{name="G",start=0.5,end=2.0}]',
    "--set", "gust.start=0.5",
    "--set", "gust.end=2.0",
    "--set", "integrator.dt=0.001",
    "--set", "integrator.duration=2.0",
]  # fmt: skip
TUNE = ["--param", "controller.smc.epsilon[2]=0.05:3", "--phase", "G", "--runs", "2",
        "--maxiter", "2", "--popsize", "3"]  # fmt: skip


def test_tune_writes_a_file_that_bases_on_the_input_and_gives_the_tuned_scenario(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "in" / "start.toml"
    src.parent.mkdir()
    src.write_text('base = "paper_stable_lateral"\n[gust]\nw20 = 15.0\n')
    out = tmp_path / "out" / "tuned.toml"
    rc = main(["tune", "--scenario", str(src), *SHORT, *TUNE, "--out", str(out),
               "--history", str(tmp_path / "h.csv")])  # fmt: skip
    assert rc == 0
    text = out.read_text()
    assert 'base = "../in/start.toml"' in text
    assert "w20" not in text  # only --set values and tuned values, the rest comes from base
    tuned = quadrs.Scenario.from_toml(out)
    value = float(capsys.readouterr().out.split("controller.smc.epsilon[2] = ")[1].split()[0])
    assert tuned["controller.smc.epsilon[2]"] == pytest.approx(value, rel=1e-5)
    assert tuned["gust.w20"] == 15.0 and tuned["integrator.dt"] == 0.001
    base = quadrs.Scenario.from_toml(src)
    assert tuned["controller.smc.epsilon"][:2] == base["controller.smc.epsilon"][:2]
    # Same seed and budget: the same file.
    again = tmp_path / "out" / "again.toml"
    assert main(["tune", "--scenario", str(src), *SHORT, *TUNE, "--out", str(again)]) == 0
    assert again.read_text() == text


@pytest.mark.parametrize(
    "param",
    ["controller.smc.epsilon[2]=1", "controller.smc.epsilon[2]=2:1", "=0:1", "x=a:b",
     "nonsense.key=0:1", "payload.mass=-1:1"],
)  # fmt: skip
def test_bad_param_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], param: str
) -> None:
    rc = main(["tune", *SHORT, "--param", param, "--phase", "G", "--out", str(tmp_path / "t.toml")])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and "error" in err
    assert not (tmp_path / "t.toml").exists()


def test_ctrl_c_saves_the_best_so_far_and_exits_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    real = opt_module.monte_carlo
    calls: list[int] = []

    def interrupted_on_the_fourth(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(opt_module, "monte_carlo", interrupted_on_the_fourth)
    out = tmp_path / "tuned.toml"
    rc = main(["tune", "--preset", "paper_stable_lateral", *SHORT, *TUNE, "--out", str(out)])
    assert rc == 130
    assert "3 evaluations" in capsys.readouterr().out
    assert quadrs.Scenario.from_toml(out)["controller.smc.epsilon[2]"] != 1.8


def test_linearize_prints_and_plots(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["linearize", "--plot", str(tmp_path), "--out", str(tmp_path / "lin.npz")])
    assert rc == 0
    out = capsys.readouterr().out
    assert "== PD ==" in out and "== SMC ==" in out and "|e_o / wind_z|" in out
    assert (tmp_path / "gust_transmissibility.png").stat().st_size > 0
    import numpy as np

    with np.load(tmp_path / "lin.npz") as z:
        assert z["pd_A"].shape == (14, 14) and z["smc_D"].shape == (20, 3)
    assert main(["linearize", "--wind", "nan"]) == 2
