"""The command table of `lotsen`: each command's module is imported only when that command runs."""

import argparse
import importlib
import subprocess
import sys

from lotsen.cli.main import COMMAND_MODULES, COMMANDS, build_parser, command_of


def test_the_command_table_lists_what_each_module_registers_with_its_help():
    listed = {}
    for module_name in COMMAND_MODULES:
        sub = argparse.ArgumentParser().add_subparsers()
        importlib.import_module(f"lotsen.cli.{module_name}").register(sub)
        for action in sub._choices_actions:
            listed[action.dest] = (module_name, action.help)
    assert listed == COMMANDS


def test_one_command_parser_has_full_arguments_and_lists_the_others():
    parser = build_parser(("recover",))
    args = parser.parse_args(["recover", "x.mcap"])
    assert callable(args.func)
    assert set(parser._subparsers._group_actions[0].choices) == set(COMMANDS)


def test_every_command_builds_its_parser_beside_the_others():
    """A module registering several commands (logs: export, replay, record, ...) meets no
    placeholder of the same name, whichever of its commands runs."""
    for name in COMMANDS:
        parser = build_parser((name,))
        choices = parser._subparsers._group_actions[0].choices
        assert set(choices) == set(COMMANDS) and choices[name].add_help, name


def test_command_of_skips_options():
    assert command_of(["--version"]) is None
    assert command_of(["run", "--sim"]) == "run"


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sys.modules))"],
                         capture_output=True, text=True, check=True).stdout
    return set(out.split())


def test_help_imports_no_numerical_library():
    loaded = _modules_after("from lotsen.cli.main import build_parser; build_parser(()).format_help()")
    assert not loaded & {"numpy", "scipy", "numba", "casadi", "matplotlib", "shapely", "fastapi"}


def test_help_lists_every_command():
    r = subprocess.run([sys.executable, "-m", "lotsen", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "calibrate-mag" in r.stdout and "recover" in r.stdout


def test_a_module_with_several_commands_is_loaded_for_any_of_them():
    for command in ("replay", "export", "record"):
        parser = build_parser((command,))
        assert set(parser._subparsers._group_actions[0].choices) == set(COMMANDS)


def test_the_program_leaves_its_objects_to_the_process_end(capsys):
    """main() as the program (argv None) freezes the collector at its end: the interpreter's last
    collections had walked every object of an identification (0.25-0.3 s after its last word). Called
    with arguments (a test, a harness) it leaves the collector alone."""
    import gc

    from lotsen.cli.main import main

    assert main([]) == 1 and gc.get_freeze_count() == 0
    capsys.readouterr()
    code = ("import atexit, gc, sys; atexit.register(lambda: print('frozen', gc.get_freeze_count() > 0)); "
            "from lotsen.cli.main import main; sys.argv = ['lotsen']; main()")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().endswith("frozen True")
