"""The config copy a harness gives `lotsen run` (the live soak and the footprint bench alike)."""

from __future__ import annotations

from pathlib import Path

from lotsen.files import read_yaml
from lotsen.runtime.config import load_config
from lotsen.stack.soak import derive_run_config


def _source(tmp_path: Path) -> Path:
    folder = tmp_path / "operator"
    folder.mkdir()
    src = folder / "boat.yaml"
    src.write_text("mode: sim\nseed: 7\nroute: routes/r.yaml\nweb: {port: 8080, pilot_token: secret-of-the-operator}\n"
                   "extra: {failsafes: {prearm_skip: [battery]}, other: 1}\n")
    return src


def test_the_copy_points_at_this_run_and_resolves_the_operators_relative_paths(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    out = derive_run_config(_source(tmp_path), work, 45678, "tok")
    assert out == work / "launch.yaml"
    data = read_yaml(out)
    assert data["route"] == str((tmp_path / "operator" / "routes" / "r.yaml").resolve())
    assert data["web"] == {"port": 45678, "pilot_token": "tok", "host": "127.0.0.1", "enabled": True}
    assert data["logging"] == {"enabled": True, "directory": str(work / "logs")}
    assert data["seed"] == 7 and "environment" not in data.get("sim", {})  # kept when not given
    assert data["extra"] == {"failsafes": {"prearm_skip": ["battery"]}, "other": 1}


def test_seed_environment_and_extra_replace_or_merge(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    out = derive_run_config(_source(tmp_path), work, 1, "t", seed=3,
                            environment={"current_speed_mps": 0.1, "current_to_deg": 90.0},
                            extra={"failsafes": {"link_timeout_s": 2.0}, "new": True})
    data = read_yaml(out)
    assert data["seed"] == 3
    assert data["sim"]["environment"] == {"current_speed_mps": 0.1, "current_to_deg": 90.0}
    assert data["extra"] == {"failsafes": {"prearm_skip": ["battery"], "link_timeout_s": 2.0}, "other": 1,
                             "new": True}


def test_the_repositorys_sim_config_survives_the_copy(tmp_path):
    root = Path(__file__).resolve().parents[2]
    out = derive_run_config(root / "config" / "sim.yaml", tmp_path, 45679, "tok", seed=5)
    config = load_config(out)
    assert config.web.port == 45679 and config.seed == 5 and config.logging.directory == str(tmp_path / "logs")
