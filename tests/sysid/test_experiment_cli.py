"""`lotsen experiment` as the README's walkthrough meets it: the design says what it is doing off a
terminal too, and a hardware run is not written under a log's name."""

from __future__ import annotations

from pathlib import Path

from lotsen.cli.main import main

EXAMPLES = Path(__file__).parents[2] / "examples" / "experiments"


def test_design_shows_progress_when_not_on_a_terminal(tmp_path, capsys):
    out = tmp_path / "d.yaml"
    assert main(["experiment", "design", "--duration", "6", "--segment", "3", "--iterations", "1",
                 "--robust-samples", "1", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "design (6 s, 1 iterations):" in err and "optimising the inputs for the information at the prior" in err
    assert out.is_file() and f"{out}: 6 s designed experiment" in err


def test_a_hardware_run_is_not_written_as_an_mcap(tmp_path, capsys):
    """`--hardware` writes the record as CSV: a RUN.mcap name would hand identify a CSV it reads as a log."""
    rc = main(["experiment", "run", str(EXAMPLES / "bow_thruster_steps.yaml"), "--hardware", "--emulated",
               "--out", str(tmp_path / "run.mcap")])
    assert rc == 2 and not (tmp_path / "run.mcap").exists()
    assert "with --hardware the record is written as CSV (give RUN.csv" in capsys.readouterr().err


def test_the_design_margin_reaches_the_design_and_a_margin_without_room_is_refused(tmp_path, capsys, monkeypatch):
    """`--margin`: the predicted track kept that far inside the area, the experiment file keeping the
    whole area (the run's check): room for a boat that turns wider than the model before it is identified."""
    import yaml

    import lotsen.sysid.design as design

    seen = []
    real = design.design_experiment
    monkeypatch.setattr(design, "design_experiment", lambda params, cfg, **kw: seen.append(cfg) or real(params, cfg, **kw))
    out = tmp_path / "d.yaml"
    common = ["experiment", "design", "--duration", "6", "--segment", "3", "--iterations", "1", "--robust-samples", "1"]
    assert main([*common, "--area", "30x20", "--margin", "6", "--out", str(out)]) == 0
    assert seen[-1].margin_m == 6.0 and seen[-1].area_size_m == (30.0, 20.0)
    area = yaml.safe_load(out.read_text())["area"]  # the run checks the whole area
    assert area == {"north_m": [-15.0, 15.0], "east_m": [-10.0, 10.0]}
    assert main([*common, "--out", str(out)]) == 0 and seen[-1].margin_m == design.DesignConfig.margin_m
    assert main([*common, "--area", "30x20", "--margin", "10", "--out", str(tmp_path / "e.yaml")]) == 2
    assert "--margin 10 m leaves no room in a 30x20 m area" in capsys.readouterr().err
    assert not (tmp_path / "e.yaml").exists()


def test_a_boat_wider_than_the_checked_model_is_turned_back_unless_told_not_to(tmp_path, capsys):
    """`experiment run --sim --out RUN.mcap` (the stack): the area check's model (`--model-params`,
    here a hull 100 x draggier, predicted to crawl) keeps a 40-s straight run inside 20 x 20 m; the
    simulated boat goes ~0.5 m/s and would leave. The run turns it back and finishes (exit 0);
    with `--no-return` the edge ends it (exit 1, the reason said)."""
    import json

    exp = tmp_path / "straight.yaml"
    exp.write_text("name: straight\narea: {size_m: [20, 20]}\npieces:\n  - {type: constant, duration_s: 40, n_rps: 40}\n")
    crawl = tmp_path / "crawl.json"
    crawl.write_text(json.dumps({"X_u": 400.0, "X_uu": -400.0, "defaults_for": [
        "m11", "m22", "m33", "Y_v", "Y_r", "Y_uv", "Y_vv", "Y_rv", "N_v", "N_r", "N_vv", "N_rr", "kappa", "C_N",
        "mu_az", "mu_t"]}))
    common = ["experiment", "run", str(exp), "--sim", "--model-params", str(crawl)]
    assert main([*common, "--out", str(tmp_path / "a.mcap")]) == 0
    err = capsys.readouterr().err
    assert "ABORTED" not in err and (tmp_path / "a.mcap").is_file()
    assert main([*common, "--no-return", "--out", str(tmp_path / "b.mcap")]) == 1
    assert "ABORTED: left the experiment area" in capsys.readouterr().err


def test_a_design_for_an_identified_model_says_so_and_its_run_is_checked_with_that_model(tmp_path, capsys):
    """`experiment design --params first.json` keeps first.json's predicted track inside the area, not the
    defaults': the file says which model it was designed for, and a run checked with the defaults that
    would leave the area names the `--params` to give (found in the README's lab loop, 6-DOF hull: a
    120-s second design refused by `experiment run` at t = 60.8 s)."""
    import json

    import yaml

    crawl = tmp_path / "crawl.json"  # a hull 100 x draggier than the defaults: predicted to crawl
    crawl.write_text(json.dumps({"X_u": 400.0, "X_uu": -400.0, "defaults_for": [
        "m11", "m22", "m33", "Y_v", "Y_r", "Y_uv", "Y_vv", "Y_rv", "N_v", "N_r", "N_vv", "N_rr", "kappa", "C_N",
        "mu_az", "mu_t"]}))
    designed = tmp_path / "d.yaml"
    assert main(["experiment", "design", "--duration", "6", "--segment", "3", "--iterations", "1",
                 "--robust-samples", "1", "--params", str(crawl), "--out", str(designed)]) == 0
    assert yaml.safe_load(designed.read_text())["description"].endswith(f"; designed for the model in {crawl}")
    capsys.readouterr()

    exp = tmp_path / "straight.yaml"  # inside 20 x 20 m for the crawling model, out of it for the defaults
    exp.write_text("name: straight\narea: {size_m: [20, 20]}\n"
                   f"description: 'a straight run; designed for the model in {crawl}'\n"
                   "pieces:\n  - {type: constant, duration_s: 40, n_rps: 40}\n")
    assert main(["experiment", "run", str(exp), "--sim", "--out", str(tmp_path / "a.csv")]) == 2
    err = capsys.readouterr().err
    assert "is predicted to leave its area" in err and "The prediction used the default coefficients" in err
    assert f"run with the same --params {crawl}" in err and not (tmp_path / "a.csv").exists()
    assert main(["experiment", "check", str(exp)]) == 2  # the check alone says the same
    assert f"checked and run with the same --params {crawl}" in capsys.readouterr().err
    assert main(["experiment", "check", str(exp), "--params", str(crawl)]) == 0
    assert main(["experiment", "run", str(exp), "--sim", "--params", str(crawl), "--out", str(tmp_path / "b.csv")]) == 0
