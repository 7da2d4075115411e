"""The ``fog-gym`` command's surface: help on every command, one error format, no stray formatting."""

import subprocess
import sys

import pytest

from fog_gym.cli import build_parser, main

COMMANDS = ("demo", "audit", "generate", "validate", "stats")


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_a_description_and_helped_options(command, capsys):
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args([command, "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"usage: fog-gym {command}") and "%%" not in text
    sub = build_parser()._subparsers._group_actions[0].choices[command]
    assert sub.description, f"{command} has no description"
    for action in sub._actions:
        assert action.help, f"{command} {action.option_strings or action.dest} has no help"


def test_bench_help_names_the_fog_gym_command():
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "bench", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith("usage: fog-gym bench")


@pytest.mark.parametrize("argv, message", [
    (["generate", "--root", "x", "--scenes", "2", "--workers", "0"], "fog-gym generate: --workers must be >= 1"),
    (["generate", "--root", "x", "--scenes", "3"], "fog-gym generate: scenes must be an even number"),
    (["generate", "--root", "x", "--scenes", "2", "--seconds", "0"], "fog-gym generate: --seconds must be > 0"),
    (["audit", "--frames", "0"], "fog-gym audit: --frames must be >= 1"),
    (["demo", "--steps", "-1"], "fog-gym demo: --steps must be >= 0"),
    (["stats", "/nonexistent/fogdrive"], "fog-gym stats: /nonexistent/fogdrive: no such folder"),
])  # fmt: skip
def test_errors_read_fog_gym_command_message(argv, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert str(e.value.code).startswith(message)


def test_generate_lays_out_fog_fields_and_validate_checks_their_records(tmp_path, capsys):
    import json

    root = tmp_path / "set"
    assert main(["generate", "--root", str(root), "--scenes", "2", "--seconds", "0.1", "--resolution", "32x24",
                 "--towns", "highway", "--fog-fields", "height"]) == 0  # fmt: skip
    assert json.loads((root / "index" / "manifest.json").read_text())["fog_fields"] == "height"
    records = sorted(root.glob("data_root/*/fog_field/*.json"))
    assert len(records) == 4 and all(json.loads(r.read_text())["fields"]["dense"]["type"] == "HeightFog" for r in records)
    assert main(["validate", str(root)]) == 0
    with pytest.raises(SystemExit) as e:
        main(["generate", "--root", str(tmp_path / "b"), "--scenes", "2", "--fog-fields", "fog"])
    assert e.value.code == 2 and "--fog-fields" in capsys.readouterr().err
