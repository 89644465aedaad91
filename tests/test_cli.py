import csv
import subprocess
import sys

from lotsen.cli.main import main


def test_model_check_prints_the_stability_report(capsys):
    assert main(["model", "check"]) == 0
    out = capsys.readouterr().out
    assert "16d at U0 = 0" in out and "FAILS" in out and "A =" in out


def test_sim_writes_a_trajectory(tmp_path, capsys):
    out = tmp_path / "traj.csv"
    assert main(["sim", "--duration", "12", "--headless", "--out", str(out), "--seed", "1"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 241  # 20 rows a second, both ends included
    assert float(rows[-1]["north"]) > 2.0
    assert "real time" in capsys.readouterr().out


def test_bad_input_is_an_error_message_not_a_traceback(tmp_path):
    bad = tmp_path / "s.yaml"
    bad.write_text("segments: [{duration_s: -1}]\n")
    r = subprocess.run([sys.executable, "-m", "lotsen", "sim", "--schedule", str(bad), "--out", str(tmp_path / "x.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.startswith("error: ") and "segments[0].duration_s: -1.0 outside" in r.stderr
    assert "Traceback" not in r.stderr
