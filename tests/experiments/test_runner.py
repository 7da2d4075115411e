"""The study runner with a toy study (no training): seeds and CIs, resume, refusal of other settings before any work,
artefacts, the report written atomically with wall times, the command line's errors; and the layout every study
shares (subcommands, ``python -m``, short example drivers, scripts without path edits)."""

import ast
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from fog_gym.experiments import runner
from fog_gym.experiments.runner import Report, Study, StudyError, Unit
from tests.helpers import ROOT


class Toy(Study):
    """Per seed, a "model" (a seeded random number written to a file), then an "evaluation" reading it back."""

    name = "toy"
    command = "fog-gym toy"

    def __init__(self, scale: float = 1.0, rows: tuple[str, ...] = ("a", "b")) -> None:
        self.scale, self.rows, self.ran = scale, rows, []

    def settings(self):
        return {"scale": self.scale}

    def units(self, seeds):
        train = [Unit("train", f"{r}_s{s}", s, {"row": r}) for s in seeds for r in self.rows]
        return train + [Unit("evaluate", f"{r}_s{s}_eval", s, {"row": r}) for s in seeds for r in self.rows]

    def artefacts(self, unit):
        return [f"models/{unit.key}.txt"] if unit.stage == "train" else []

    def run_unit(self, unit, out, progress):
        self.ran.append(unit.key)
        if unit.stage == "train":
            value = float(np.random.default_rng([unit.seed, ord(unit.params["row"])]).normal()) * self.scale
            runner.write_atomic(out / "models" / f"{unit.key}.txt", repr(value))
            return {"value": value}
        return {"read": float((out / "models" / f"{unit.params['row']}_s{unit.seed}.txt").read_text()), "episodes": [1.0, 3.0]}

    def report(self, records, out, seeds):
        cells = {}
        for r in records.values():
            if r["stage"] == "evaluate":
                cells.setdefault(r["params"]["row"], {}).setdefault("x", {})[r["seed"]] = r["result"]
        table = runner.aggregate(cells)
        text = "\n".join(f"| {row} | {runner.fmt_stat(table[row]['x']['read'], '{:.3f}')} |" for row in table)
        return Report(text, {"table": table}, "toy.md", "toy.json", {"toy.png": self.figure})

    @staticmethod
    def figure(path):
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots()
        ax.plot([0, 1])
        runner.save_figure(fig, path)


def test_seeds_repeat_every_unit_and_the_table_gives_the_student_t_ci(tmp_path):
    study = Toy()
    report = runner.run(study, tmp_path, seeds=3, progress=False, log=lambda *_: None)
    values = [float((tmp_path / "models" / f"a_s{s}.txt").read_text()) for s in range(3)]
    cell = report.data["table"]["a"]["x"]["read"]
    assert cell["mean"] == pytest.approx(np.mean(values)) and cell["seeds"] == 3
    assert cell["ci95"] == pytest.approx(stats.t.interval(0.95, 2, scale=stats.sem(values))[1])
    episodes = report.data["table"]["a"]["x"]["episodes"]
    assert episodes["episodes"] == 6 and episodes["episode_std"] == pytest.approx(np.std([1, 3] * 3, ddof=1))
    assert len(study.ran) == 12 and study.ran[:4] == ["a_s0", "b_s0", "a_s1", "b_s1"]  # stage by stage, seed-major
    assert (tmp_path / "toy.md").read_text().startswith(f"| a | {np.mean(values):.3f} ± {cell['ci95']:.3f} |")
    assert json.loads((tmp_path / "toy.json").read_text())["runner"]["seeds"] == [0, 1, 2]
    assert (tmp_path / "toy.png").read_bytes()[:4] == b"\x89PNG" and not list(tmp_path.rglob(".*"))


def test_a_second_run_keeps_finished_units_adds_seeds_and_reruns_a_unit_whose_artefact_is_gone(tmp_path):
    first = runner.run(Toy(), tmp_path, seeds=1, progress=False, log=lambda *_: None)
    said, again = [], Toy()
    second = runner.run(again, tmp_path, seeds=2, progress=False, log=said.append)
    assert again.ran == ["a_s1", "b_s1", "a_s1_eval", "b_s1_eval"]  # seed 0 kept, seed 1 added
    assert sum(s.endswith("kept from " + str(tmp_path / "train" / "a_s0.json")) for s in said) == 1
    kept = json.loads((tmp_path / "evaluate" / "a_s0_eval.json").read_text())
    assert kept["result"]["read"] == first.data["table"]["a"]["x"]["read"]["mean"] and kept["wall_s"] >= 0
    assert second.data["runner"]["units"]["a_s0"]["kept"] and not second.data["runner"]["units"]["a_s1"]["kept"]
    (tmp_path / "models" / "b_s0.txt").unlink()  # a record without its model is not finished
    third = Toy()
    runner.run(third, tmp_path, seeds=2, progress=False, log=lambda *_: None)
    assert third.ran == ["b_s0"]


def test_a_kept_folder_carries_finished_units_to_a_new_output_folder_and_the_same_report(tmp_path):
    keep, first_out, second_out = tmp_path / "kept", tmp_path / "session1", tmp_path / "session2"
    first = runner.run(Toy(), first_out, seeds=1, progress=False, log=lambda *_: None, keep=keep)
    assert sorted(str(p.relative_to(keep)) for p in keep.rglob("*") if p.is_file()) == [
        "evaluate/a_s0_eval.json", "evaluate/b_s0_eval.json", "models/a_s0.txt", "models/b_s0.txt", "study.json",
        "train/a_s0.json", "train/b_s0.json"]  # records, their files and the study record; no report, no temporaries
    said, later = [], Toy()  # a new session: its output folder is gone, the kept folder came back from git
    second = runner.run(later, second_out, seeds=2, progress=False, log=said.append, keep=keep)
    assert later.ran == ["a_s1", "b_s1", "a_s1_eval", "b_s1_eval"]
    assert sum(s.endswith("restored from " + str(keep)) for s in said) == 4
    assert second.data["table"]["a"]["x"]["read"]["seeds"] == 2 and (keep / "train" / "a_s1.json").exists()
    seed0 = json.loads((keep / "evaluate" / "a_s0_eval.json").read_text())["result"]["read"]
    assert seed0 == first.data["table"]["a"]["x"]["read"]["mean"]
    with pytest.raises(StudyError, match=r"kept.* holds a toy study with other settings"):
        runner.run(Toy(scale=2.0), tmp_path / "session3", progress=False, log=lambda *_: None, keep=keep)
    with pytest.raises(ValueError, match="keep must be another folder than out"):
        runner.run(Toy(), keep, progress=False, log=lambda *_: None, keep=keep)


def test_units_finished_before_keep_was_asked_for_are_copied_to_the_kept_folder(tmp_path):
    runner.run(Toy(rows=("a",)), tmp_path / "out", progress=False, log=lambda *_: None)
    again = Toy(rows=("a",))
    runner.run(again, tmp_path / "out", progress=False, log=lambda *_: None, keep=tmp_path / "kept")
    assert again.ran == [] and (tmp_path / "kept" / "models" / "a_s0.txt").read_text() == (
        tmp_path / "out" / "models" / "a_s0.txt").read_text()


def test_the_report_says_every_units_wall_time_and_the_total(tmp_path):
    report = runner.run(Toy(rows=("a",)), tmp_path, seeds=2, progress=False, log=lambda *_: None)
    text = (tmp_path / "toy.md").read_text()
    assert "## Wall time" in text and "| a_s1_eval | evaluate |" in text and "Units in all:" in text
    units = report.data["runner"]["units"]
    assert set(units) == {"a_s0", "a_s1", "a_s0_eval", "a_s1_eval"} and all(u["wall_s"] >= 0 for u in units.values())
    assert report.data["runner"]["units_s"] == pytest.approx(sum(u["wall_s"] for u in units.values()))


def test_other_settings_or_another_study_are_refused_before_any_work(tmp_path):
    runner.run(Toy(), tmp_path, progress=False, log=lambda *_: None)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    other = Toy(scale=2.0)
    with pytest.raises(StudyError, match=r"holds a toy study with other settings \(scale: 1.0 there, 2.0 here\)"):
        runner.run(other, tmp_path, progress=False, log=lambda *_: None)
    Toy.name = "other"
    try:
        with pytest.raises(StudyError, match="holds a 'toy' study, not 'other'"):
            runner.run(Toy(), tmp_path, progress=False, log=lambda *_: None)
    finally:
        Toy.name = "toy"
    assert other.ran == [] and sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
    (tmp_path / "study.json").write_text("not json")
    with pytest.raises(StudyError, match="not a study record"):
        runner.run(Toy(), tmp_path, progress=False, log=lambda *_: None)


class ToyData(Toy):
    """The toy study on "data": a content digest and the scenes its units read."""

    def __init__(self, digest: str, scenes: tuple[str, ...] = ("s1", "s2")) -> None:
        super().__init__()
        self.digest, self.scenes = digest, scenes

    def prepare(self, log, progress):
        return {"digest": self.digest, "scenes": list(self.scenes)}


def test_data_regenerated_on_another_machine_is_taken_only_when_its_digest_is_named(tmp_path):
    keep, quiet = tmp_path / "kept", {"progress": False, "log": lambda *_: None}
    runner.run(ToyData("sha256:aaa"), tmp_path / "s1", **quiet, keep=keep)
    other = ToyData("sha256:bbb")
    with pytest.raises(StudyError, match=r"other data \(digest: .*, pass --accept-data sha256:bbb$"):
        runner.run(other, tmp_path / "s2", **quiet, keep=keep)
    assert other.ran == [] and not (tmp_path / "s2" / "train").exists()
    with pytest.raises(StudyError, match="other data"):  # naming another digest takes nothing
        runner.run(other, tmp_path / "s2", **quiet, keep=keep, accept_data="sha256:ccc")
    runner.run(other, tmp_path / "s2", **quiet, keep=keep, accept_data="sha256:bbb")
    assert other.ran == []  # every unit restored from the kept folder, none run again
    record = json.loads((keep / "study.json").read_text())["data"]
    assert record["digest"] == "sha256:aaa" and record["equivalent_digests"] == ["sha256:bbb"]
    for digest in ("sha256:aaa", "sha256:bbb"):  # afterwards either machine's data is taken without the flag
        again = ToyData(digest)
        runner.run(again, tmp_path / f"s3_{digest[-3:]}", **quiet, keep=keep)
        assert again.ran == []
    assert json.loads((keep / "study.json").read_text())["data"] == record  # and the record stays as it was
    with pytest.raises(StudyError, match=r"scenes: .*here\); use another --out, or the same settings to resume it$"):
        runner.run(ToyData("sha256:ddd", ("s1",)), tmp_path / "s4", **quiet, keep=keep, accept_data="sha256:ddd")


def test_ray_without_the_extra_is_refused_before_any_work(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    study = Toy()
    with pytest.raises(StudyError, match=r"--ray needs the optional 'ray' extra: pip install 'fog-gym\[ray\]'"):
        runner.run(study, tmp_path / "out", ray_address="auto", progress=False)
    assert study.ran == [] and not (tmp_path / "out").exists()


@pytest.mark.parametrize("jobs, ray, message", [(0, None, "jobs must be a positive integer"),
                                                 (True, None, "jobs must be a positive integer"),
                                                 (2, "auto", "exclude each other")])  # fmt: skip
def test_bad_jobs_are_refused_before_any_work(jobs, ray, message, tmp_path):
    study = Toy()
    with pytest.raises(ValueError, match=message):
        runner.run(study, tmp_path / "out", jobs=jobs, ray_address=ray, progress=False)
    assert study.ran == [] and not (tmp_path / "out").exists()


@pytest.mark.parametrize("seeds", [0, -1, True, 1.5])
def test_seeds_must_be_a_positive_integer(seeds, tmp_path):
    with pytest.raises(ValueError, match="seeds must be a positive integer"):
        runner.run(Toy(), tmp_path, seeds=seeds, progress=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=12))
def test_the_ci_is_the_student_t_half_width_and_none_for_one_seed(values):
    ci = runner.ci95_across(values)
    if len(values) == 1:
        assert ci is None
        return
    sd = np.std(values, ddof=1)
    assert ci == pytest.approx(stats.t.ppf(0.975, len(values) - 1) * sd / math.sqrt(len(values)), abs=1e-9)
    table = runner.aggregate({"r": {"c": {k: {"m": v} for k, v in enumerate(values)}}})
    cell = table["r"]["c"]["m"]
    assert min(values) - 1e-9 <= cell["mean"] <= max(values) + 1e-9 and cell["seeds"] == len(values)


def test_atomic_writes_leave_nothing_behind_when_drawing_fails(tmp_path):
    (tmp_path / "fig.png").write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with runner.atomic_path(tmp_path / "fig.png") as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("drawing failed")
    assert (tmp_path / "fig.png").read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["fig.png"]
    runner.write_atomic(tmp_path / "a" / "x.json", {"k": (1, 2)})
    assert json.loads((tmp_path / "a" / "x.json").read_text()) == {"k": [1, 2]}


# -- one layout for every study ---------------------------------------------------------------------------------
STUDIES = {"exp1": "detection3d", "exp2": "defog", "rl-bench": "rl_bench"}


@pytest.mark.parametrize("command, package", STUDIES.items())
def test_every_study_is_a_subcommand_and_a_module_with_help_smoke_seeds_and_ray(command, package):
    for argv in (["fog_gym.cli", command, "--help"], [f"fog_gym.experiments.{package}", "--help"]):
        out = subprocess.run([sys.executable, "-m", *argv], capture_output=True, text=True, cwd=ROOT)
        assert out.returncode == 0, out.stderr
        assert out.stdout.startswith(f"usage: fog-gym {command}")
        assert all(flag in out.stdout for flag in ("--smoke", "--seeds", "--ray", "--out"))
    modules = {p.stem for p in (ROOT / "fog_gym" / "experiments" / package).glob("*.py")}
    assert {"__main__", "train", "evaluate", "report", "study"} <= modules and modules & {"data", "protocol"}


@pytest.mark.parametrize("command", STUDIES)
def test_a_bad_option_is_a_usage_error_before_any_work(command, tmp_path):
    argv = [command, "--seeds", "0", "--out", str(tmp_path / "out")]
    if command != "rl-bench":
        argv += ["--root", str(tmp_path / "none")]
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", *argv], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2 and f"fog-gym {command}: error: --seeds must be >= 1" in out.stderr
    assert not (tmp_path / "out").exists()


def test_a_missing_dataset_reads_fog_gym_command_message(tmp_path):
    from fog_gym.cli import main

    with pytest.raises(SystemExit) as e:
        main(["exp1", "--root", str(tmp_path / "none"), "--out", str(tmp_path / "out")])
    assert str(e.value.code).startswith(f"fog-gym exp1: {tmp_path / 'none'}")


def test_examples_are_short_drivers_and_scripts_edit_no_import_path():
    for path in sorted((ROOT / "examples").glob("*.py")):
        tree = ast.parse(path.read_text())
        if any(isinstance(n, ast.ImportFrom) and (n.module or "").startswith("fog_gym.experiments") for n in ast.walk(tree)):
            assert len(path.read_text().splitlines()) <= 40, f"{path.name} is a driver: keep it short"
    for path in sorted([*(ROOT / "scripts").glob("*.py"), *(ROOT / "examples").glob("*.py")]):
        assert "sys.path" not in path.read_text(), path.name


def test_the_resume_script_answers_help_and_refuses_bad_arguments_before_work(tmp_path):
    script = ROOT / "scripts" / "resume_studies.sh"
    env = {"PATH": "/usr/bin:/bin", "DATA": str(tmp_path / "data"), "RUNS": str(tmp_path / "runs")}
    helped = subprocess.run(["bash", str(script), "--help"], capture_output=True, text=True, env=env)
    assert helped.returncode == 0 and "--keep" in helped.stdout and "exp1|exp2|both" in helped.stdout
    cases = ((["exp3"], "unknown study 'exp3'"), (["both", "--", "--epochs", "1"], "go to one study"),
             (["exp2"], "from the repository root"))  # tmp_path is not the repository
    for args, says in cases:
        bad = subprocess.run(["bash", str(script), *args], capture_output=True, text=True, env=env, cwd=tmp_path)
        assert bad.returncode == 2 and says in bad.stderr and bad.stderr.count("\n") == 1
    assert not (tmp_path / "data").exists()  # refused before any work
