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
