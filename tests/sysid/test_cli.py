import json

import pytest

from lotsen.cli.identify import main_standalone
from lotsen.sysid.data import save_csv
from lotsen.sysid.estimate import NAMES


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory, short_run):
    p = tmp_path_factory.mktemp("cli") / "run.csv"
    save_csv(short_run.record, p)
    return p


def test_identify_writes_params_and_report(run_csv, tmp_path, capsys):
    out, rep = tmp_path / "p.json", tmp_path / "r.html"
    rc = main_standalone(["identify", str(run_csv), "--out", str(out), "--report", str(rep),
                          "--fix", "kappa=0.02", "--fix", "Y_rv=-2", "--fix", "N_vv=-1"])
    assert rc == 0
    err = capsys.readouterr().err
    assert "WARNING" in err and "m11 = 14.0" in err  # default scale announced loudly
    data = json.loads(out.read_text())
    assert set(data) == set(NAMES) | {"std"}
    assert data["m11"] == 14.0 and data["kappa"] == 0.02
    assert set(data["std"]) == set(NAMES) - {"m11", "kappa", "Y_rv", "N_vv"}
    html = rep.read_text()
    assert html.startswith("<!DOCTYPE html>") and "data:image/png;base64," in html and "black-box" in html


def test_identify_writes_a_pdf_report(run_csv, tmp_path):
    rep = tmp_path / "r.pdf"
    assert main_standalone(["identify", str(run_csv), "--out", str(tmp_path / "p.json"), "--report", str(rep),
                            "--fix", "kappa=0.02", "--fix", "Y_rv=-2", "--fix", "N_vv=-1"]) == 0
    pdf = rep.read_bytes()
    pages = pdf.count(b"/Type /Page") - pdf.count(b"/Type /Pages")
    assert pdf.startswith(b"%PDF") and pages == 5  # summary + residuals, validation, track, estimation


def test_cli_errors_are_clean(run_csv, tmp_path, capsys):
    assert main_standalone(["identify", str(run_csv), "--out", str(tmp_path / "p.json"), "--fix", "m99=1"]) == 2
    assert "unknown parameter 'm99'" in capsys.readouterr().err
    assert main_standalone(["identify", str(run_csv), "--out", str(tmp_path / "p.json"), "--no-default-scale"]) == 2
    assert "unidentifiable" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("t,alpha1,alpha2,n1,n2,nt,north,east,psi,r\n0,0,0,0,0,0,0,0,0,x\n")
    assert main_standalone(["identify", str(bad), "--out", str(tmp_path / "p.json")]) == 2
    assert "row 2, column r" in capsys.readouterr().err


def test_experiment_run_requires_sim_and_writes_csv(tmp_path, capsys):
    from pathlib import Path

    exp = Path(__file__).parents[2] / "examples" / "experiments" / "bow_thruster_steps.yaml"
    assert main_standalone(["experiment", "run", str(exp), "--out", str(tmp_path / "x.csv")]) == 2
    assert "--sim (simulated boat) or --hardware" in capsys.readouterr().err
    assert main_standalone(["experiment", "run", str(exp), "--sim", "--out", str(tmp_path / "x.csv")]) == 0
    head = (tmp_path / "x.csv").read_text().splitlines()[0]
    assert head == "t,alpha1,alpha2,n1,n2,nt,north,east,psi,r"


def test_simulated_measurements_match_truth(short_run):
    import numpy as np

    rec, tt, tx = short_run.record, short_run.truth_t, short_run.truth_x
    ok = np.isfinite(rec.outputs[:, 0])
    idx = np.searchsorted(tt, rec.t[ok] - 1e-9)
    err_ne = rec.outputs[ok, :2] - tx[idx, :2]
    assert 0.003 < np.std(err_ne) < 0.03  # RTK fixed, 1 cm
    dpsi = np.angle(np.exp(1j * (rec.outputs[ok, 2] - tx[idx, 2])))
    assert 0.005 < np.std(dpsi) < 0.02
    assert abs(np.mean(rec.outputs[ok, 3] - tx[idx, 5])) < 0.003  # gyro bias removed
