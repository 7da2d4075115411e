"""Every example answers ``--help`` with its usage and starts no work (nothing written, quickly)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.py"))


def test_every_example_answers_help_without_starting_work(tmp_path):
    assert len(EXAMPLES) >= 5
    runs = {}
    for ex in EXAMPLES:  # all at once: each only parses its arguments
        cwd = tmp_path / ex.stem
        cwd.mkdir()
        runs[ex.name] = (cwd, subprocess.Popen([sys.executable, str(ex), "--help"], cwd=cwd, text=True,
                                               stdout=subprocess.PIPE, stderr=subprocess.PIPE))  # fmt: skip
    for name, (cwd, proc) in runs.items():
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, (name, err)
        assert out.startswith("usage: "), (name, out)
        assert "--help" in out and list(cwd.iterdir()) == [], name  # no output folder, no data


def test_the_experiment_examples_build_valid_studies_without_running_them(tmp_path):
    """The experiments' examples build their study at the example's budget (a config the study accepts), and
    building it starts no work; running one takes minutes (exp1 example: 3 min on 2 cores), so it is not run here."""
    from fog_gym.experiments.runner import Study
    from tests.helpers import load_module

    for name in ("exp1_detection3d", "exp2_defog_vs_fog"):
        study = load_module(f"examples/{name}.py").study(tmp_path / name)
        assert isinstance(study, Study) and study.settings(), name
        assert not (tmp_path / name).exists(), name


@pytest.mark.parametrize("order", ["sideways", "shuffle:x"])
def test_a_bad_test_order_is_a_usage_error_before_any_test_runs(order):
    import os

    env = {**os.environ, "FOG_GYM_TEST_ORDER": order}
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
                          str(Path(__file__)), "-k", "help"], env=env, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert out.returncode == 4, out.stdout + out.stderr  # pytest's usage error
    assert f"FOG_GYM_TEST_ORDER must be 'reverse' or 'shuffle:<seed>', got '{order}'" in out.stdout + out.stderr
    assert " passed" not in out.stdout
