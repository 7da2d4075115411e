"""The one study runner: seeds, resume, progress, wall times and the report of every fog-gym study.

A study — Experiment 1 (:mod:`fog_gym.experiments.detection3d`), Experiment 2 (:mod:`fog_gym.experiments.defog`),
the RL benchmark (:mod:`fog_gym.experiments.rl_bench`) — is a :class:`Study`: its settings, the units of work it
splits into (a trained model, an evaluation cell: each with a stage, a key and a seed), how to run one unit and
how to turn the finished units into a report. :func:`run` does the rest, the same way for every study:

* **seeds**: ``--seeds K`` repeats every unit for K seeds; tables give the mean over seeds and the half-width of
  the 95 % Student-t interval across seeds (:func:`ci95_across`, :func:`aggregate`, :func:`fmt_stat`);
* **resume**: ``<out>/study.json`` records the study and its settings before any unit runs; a finished unit is
  kept as ``<out>/<stage>/<key>.json`` (with the files it wrote) and never runs again; a run with other settings
  into the same folder is refused with :class:`StudyError` before any work (which seeds, rows or conditions run
  is not a setting: a later run may add some); a training unit keeps its state after every epoch
  (:class:`EpochCheckpoint`, ``<out>/checkpoints/<key>.pt``), so a killed run resumes inside a unit, from its
  last finished epoch, to the weights an uninterrupted run reaches;
* **progress**: one bar per stage over its units (the units show their own bars beneath);
* **wall times**: of every unit (kept in its record) and of the whole run, in the Markdown and the JSON;
* **the report**: Markdown, JSON and PNG files, each written atomically (a temporary file, then ``os.replace``);
* **Ray**: ``--ray ADDRESS`` runs the units of each stage as Ray tasks on an existing cluster (the ``ray`` extra)
  with the same seeds, so the same results as a local run; ``<out>`` must be storage every node sees;
* **local jobs**: ``--jobs N`` runs up to N units of a stage at once in worker processes on this machine (same
  seeds, same results). Worth it where one unit leaves cores idle: an RL agent whose learner runs on one thread;
* **kept units**: ``--keep DIR`` copies the study record and every finished unit (its record and files) into a
  second folder meant to be committed or synced, and restores from it the units ``<out>`` lacks: a study then
  spans machines and sessions whose ``<out>`` (and its caches and checkpoints) does not survive. ``DIR`` is checked
  like ``<out>``: another study, other settings or other data are refused before any work.

Example:
    >>> round(ci95_across([1.0, 2.0, 3.0]), 3), ci95_across([1.0]) is None
    (2.484, True)
    >>> fmt_stat({"mean": 0.25, "ci95": 0.05}, "{:.2f}"), fmt_stat({"mean": 0.25, "ci95": None}, "{:.2f}")
    ('0.25 ± 0.05', '0.25')
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST = "study.json"


class StudyError(ValueError):
    """A run that must not start (another study or other settings in the folder, Ray missing): said before work."""


@dataclass(frozen=True)
class Unit:
    """One piece of a study's work: ``stage`` (a folder under the output, run in the order stages first appear),
    ``key`` (a file name, unique in its stage), ``seed``, ``params`` (JSON) and the CPUs it occupies (Ray)."""

    stage: str
    key: str
    seed: int
    params: Mapping[str, Any] = field(default_factory=dict)
    cpus: int = 1


@dataclass
class Report:
    """What a study reports: the Markdown (``md_name``) and the JSON (``json_name``) written in the output folder,
    and figures, each a function that draws into the path it is given."""

    markdown: str
    data: dict[str, Any]
    md_name: str
    json_name: str
    figures: dict[str, Callable[[Path], None]] = field(default_factory=dict)


class Study:
    """The interface :func:`run` drives (see the module docstring). Subclasses set :attr:`name` and
    :attr:`command`, and implement :meth:`settings`, :meth:`units`, :meth:`run_unit` and :meth:`report`; the
    command line comes from :meth:`add_arguments` and :meth:`from_args`."""

    name = "study"
    command = "fog-gym study"
    description = ""
    default_out = Path("out/study")
    smoke_help = "a small budget that checks the whole pipeline"
    #: The study renders its own wall-time table (else the runner appends one per unit).
    own_wall_times = False
    #: The run's output folder, set by :func:`run` before :meth:`prepare`.
    output: Path = Path(".")

    def settings(self) -> dict[str, Any]:
        """Everything a finished unit depends on (JSON); compared with the output folder's before any work."""
        raise NotImplementedError

    def prepare(self, log: Callable[[str], None], progress: bool) -> dict[str, Any]:
        """Data work before the units (e.g. generating or opening a dataset); returns what the units depend on
        in it (e.g. the chosen scenes), compared with the output folder's like :meth:`settings`."""
        return {}

    def seed_list(self, k: int) -> list[int]:
        """The seeds of ``--seeds k``."""
        return list(range(k))

    def units(self, seeds: Sequence[int]) -> list[Unit]:
        raise NotImplementedError

    def artefacts(self, unit: Unit) -> list[str]:
        """Files (relative to the output folder) a finished unit leaves; a record without them is run again."""
        return []

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        """Run one unit (it may write artefacts under ``out``); returns its JSON result."""
        raise NotImplementedError

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        """One line logged when a unit finishes."""
        return ""

    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        """The report from every unit's record (``records[key]``: ``stage``, ``seed``, ``params``, ``result``,
        ``wall_s``)."""
        raise NotImplementedError

    def announce(self, seeds: Sequence[int]) -> str:
        """A line printed before any work (e.g. that this is a smoke run)."""
        return ""

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """The study's own command-line options (the runner adds ``--out``, ``--seeds``, ``--smoke``, ``--ray``, ``--jobs``)."""

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Study:
        """The study of parsed arguments; a ValueError names the bad option."""
        raise NotImplementedError


# -- statistics across seeds ------------------------------------------------------------------------------------
def ci95_across(values: Sequence[float]) -> float | None:
    """Half-width of the 95 % Student-t interval of the mean of ``values``; None for fewer than two."""
    if len(values) < 2:
        return None
    from scipy import stats

    return float(stats.t.ppf(0.975, len(values) - 1) * np.std(values, ddof=1) / math.sqrt(len(values)))


def aggregate(cells: Mapping[str, Mapping[str, Mapping[int, Mapping[str, Any]]]],
              metrics: Sequence[str] | None = None) -> dict[str, dict[str, dict[str, dict[str, Any]]]]:  # fmt: skip
    """``cells[row][column][seed][metric]`` → ``table[row][column][metric]``: ``mean`` over seeds, ``ci95``
    across seeds (None for one), ``seeds``. A metric given as a list (one value per episode) counts by its mean
    per seed and adds the episode-level ``episode_std`` and ``episodes``. ``metrics`` default: every numeric key
    (a seed without a metric does not count for it).

    >>> t = aggregate({"r": {"c": {0: {"m": 1.0}, 1: {"m": 3.0}}}})
    >>> t["r"]["c"]["m"]["mean"], round(t["r"]["c"]["m"]["ci95"], 2), t["r"]["c"]["m"]["seeds"]
    (2.0, 12.71, 2)
    >>> aggregate({"r": {"c": {0: {"m": [0.0, 1.0]}}}})["r"]["c"]["m"]
    {'mean': 0.5, 'ci95': None, 'seeds': 1, 'episode_std': 0.7071067811865476, 'episodes': 2}
    """
    table: dict[str, Any] = {}
    for row, columns in cells.items():
        for col, seeds in columns.items():
            names = metrics or list(dict.fromkeys(
                k for s in seeds.values() for k, v in s.items()
                if isinstance(v, (int, float, list)) and not isinstance(v, bool)))  # fmt: skip
            for metric in names:
                values = [seeds[s][metric] for s in sorted(seeds) if metric in seeds[s]]
                per_seed = [float(np.mean(v)) for v in values]
                cell: dict[str, Any] = {"mean": float(np.mean(per_seed)), "ci95": ci95_across(per_seed),
                                        "seeds": len(per_seed)}  # fmt: skip
                if values and isinstance(values[0], list):
                    episodes = [float(e) for v in values for e in v]
                    cell["episode_std"] = float(np.std(episodes, ddof=1)) if len(episodes) > 1 else 0.0
                    cell["episodes"] = len(episodes)
                table.setdefault(row, {}).setdefault(col, {})[metric] = cell
    return table


def fmt_stat(stat: Mapping[str, Any], fmt: str, na: str | None = None) -> str:
    """``mean ± ci95`` with ``fmt``; for one seed the mean alone, or ``mean ± na`` when ``na`` is given."""
    mean = fmt.format(stat["mean"])
    if stat.get("ci95") is None:
        return mean if na is None else f"{mean} ± {na}"
    return f"{mean} ± {fmt.format(stat['ci95'])}"


# -- files -----------------------------------------------------------------------------------------------------
def write_atomic(path: Path, data: str | bytes | dict | list) -> Path:
    """Write text, bytes or JSON (dicts and lists, indented) to ``path`` through a temporary file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    if isinstance(data, (dict, list)):
        data = json.dumps(data, indent=1)
    tmp.write_bytes(data if isinstance(data, bytes) else data.encode())
    os.replace(tmp, path)
    return path


def write_report(out: Path, stem: str, text: str, results: Any) -> None:
    """Write ``<stem>.md`` (``text``) and ``<stem>.json`` (``results``) into ``out``, each atomically."""
    write_atomic(Path(out) / f"{stem}.md", text + "\n")
    write_atomic(Path(out) / f"{stem}.json", _jsonable(results))


@contextmanager
def atomic_path(path: Path):
    """A temporary path with ``path``'s suffix to write to; it replaces ``path`` when the block ends cleanly."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class EpochCheckpoint:
    """A training unit's state after its last finished epoch (``torch.save`` of a dict, written atomically).

    ``signature`` names what the state belongs to (the unit's settings and its number of steps per epoch): a
    checkpoint with another signature is ignored, never loaded. ``path=None`` keeps nothing (tests, one-off fits).
    The trainer saves the model, optimiser, schedule, data-order generator and its own history after each epoch
    and, when it starts, continues from :meth:`load`'s state; the study calls :meth:`clear` once the unit's files
    are written.
    """

    def __init__(self, path: Path | None, signature: Mapping[str, Any]) -> None:
        self.path = None if path is None else Path(path)
        self.signature = dict(signature)

    def load(self) -> dict[str, Any] | None:
        """The saved state, or None when there is none (or it belongs to other settings)."""
        import torch

        if self.path is None or not self.path.exists():
            return None
        state = torch.load(self.path, map_location="cpu", weights_only=False)
        return state if state.get("signature") == self.signature else None

    def save(self, state: Mapping[str, Any]) -> None:
        import torch

        if self.path is not None:
            with atomic_path(self.path) as tmp:
                torch.save(dict(state) | {"signature": self.signature}, tmp)

    def clear(self) -> None:
        if self.path is not None:
            self.path.unlink(missing_ok=True)

    def resume(self, model: Any, opt: Any, sched: Any, order: Any) -> dict[str, Any] | None:
        """Load the saved state into the model, optimiser, schedule and data-order generator (and the global torch
        generator); returns the trainer's own part of it (``epoch``, ``step``, ``seconds``, its history), or None."""
        import torch

        state = self.load()
        if state is not None:
            model.load_state_dict(state["model"])
            opt.load_state_dict(state["opt"])
            sched.load_state_dict(state["sched"])
            order.set_state(state["order"])
            torch.set_rng_state(state["rng"])
        return state

    def save_epoch(self, model: Any, opt: Any, sched: Any, order: Any, **extra: Any) -> None:
        """Save the state after an epoch: what :meth:`resume` restores, and ``extra`` (the trainer's own part)."""
        import torch

        if self.path is not None:
            self.save({"model": model.state_dict(), "opt": opt.state_dict(), "sched": sched.state_dict(),
                       "order": order.get_state(), "rng": torch.get_rng_state(), **extra})  # fmt: skip


def save_figure(fig: Any, path: Path, **kwargs: Any) -> None:
    """``fig.savefig`` atomically, then close the figure."""
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)
    plt.close(fig)


def _jsonable(x: Any) -> Any:
    return json.loads(json.dumps(x))


def check_manifest(out: Path, study: str, settings: Mapping[str, Any], data: Mapping[str, Any] | None = None,
                   accept_data: str | None = None) -> None:
    """Refuse an output folder that holds another study, or this study with other settings (or other data, when
    ``data`` is given), naming what differs. The data's ``digest`` matches the record's own or one it lists as
    equivalent (``equivalent_digests``); ``accept_data`` names one more digest to take as equivalent (the data
    regenerated by the same command on another machine, see :func:`record_data`)."""
    path = Path(out) / MANIFEST
    if not path.exists():
        return
    try:
        kept = json.loads(path.read_text())
    except json.JSONDecodeError:
        raise StudyError(f"{path} is not a study record; use another --out") from None
    if not isinstance(kept, dict) or kept.get("study") != study:
        other = kept.get("study") if isinstance(kept, dict) else None
        raise StudyError(f"{out} holds {'a ' + repr(other) if other else 'another'} study, not {study!r}; use another --out")
    for part, want in (("settings", settings), ("data", data)):
        if want is None or (part == "data" and part not in kept):
            continue
        have, want = dict(kept.get(part, {})), _jsonable(want)
        if part == "data":
            same = {have.get("digest"), *have.pop("equivalent_digests", []), accept_data} - {None}
            if want.get("digest") in same:
                have["digest"] = want.get("digest")
        keys = [k for k in sorted(set(have) | set(want)) if have.get(k) != want.get(k)]
        diffs = [f"{k}: {json.dumps(have.get(k))} there, {json.dumps(want.get(k))} here" for k in keys]
        if diffs:
            shown = "; ".join(d if len(d) < 160 else d[:157] + "..." for d in diffs[:4])
            more = f" and {len(diffs) - 4} more" if len(diffs) > 4 else ""
            hint = ""
            if part == "data" and keys == ["digest"]:
                hint = ("; if this data was regenerated by the documented command on another machine (numpy's SIMD "
                        "kernels differ in the last bit between CPUs) and matches the kept units' (see the runner's "
                        f"docs), pass --accept-data {want['digest']}")  # fmt: skip
            raise StudyError(f"{out} holds a {study} study with other {part} ({shown}{more}); use another --out, or "
                             f"the same settings to resume it{hint}")  # fmt: skip


def record_data(out: Path, data: Mapping[str, Any]) -> dict[str, Any]:
    """The ``data`` entry to write into ``out``'s study record: ``data`` itself for a new record; for a kept one,
    its first digest stays ``digest`` and every other digest accepted for it (:func:`check_manifest`) joins
    ``equivalent_digests``, so that data regenerated on either machine is taken afterwards."""
    data, path = _jsonable(data), Path(out) / MANIFEST
    kept = json.loads(path.read_text()).get("data") if path.exists() else None
    if not isinstance(kept, dict) or "digest" not in kept or "digest" not in data:
        return data
    others = sorted((set(kept.get("equivalent_digests", [])) | {data["digest"]}) - {kept["digest"]})
    return {**data, "digest": kept["digest"]} | ({"equivalent_digests": others} if others else {})


def torch_device(name: str) -> Any:
    """``auto`` (the GPU when present, else the CPU) or a torch device name, as a ``torch.device``."""
    import torch

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def import_ray() -> Any:
    """The ``ray`` module, or a :class:`StudyError` that says how to install it."""
    try:
        import ray
    except ImportError:
        raise StudyError("--ray needs the optional 'ray' extra: pip install 'fog-gym[ray]'") from None
    return ray


# -- running ---------------------------------------------------------------------------------------------------
def _execute(study: Study, unit: Unit, out: str, progress: bool) -> tuple[dict[str, Any], float]:
    """Run one unit and time it (locally, or inside a Ray task)."""
    t0 = time.perf_counter()
    result = study.run_unit(unit, Path(out), progress)
    return result, time.perf_counter() - t0


def _record_path(out: Path, unit: Unit) -> Path:
    return out / unit.stage / f"{unit.key}.json"


def _finished(study: Study, out: Path, unit: Unit) -> dict[str, Any] | None:
    path = _record_path(out, unit)
    if not path.exists() or not all((out / a).exists() for a in study.artefacts(unit)):
        return None
    return json.loads(path.read_text())


def _copy_unit(study: Study, src: Path, dst: Path, unit: Unit) -> None:
    """Copy a finished unit's files, then its record (last: a record in ``dst`` means its files are there)."""
    for rel in (*study.artefacts(unit), str(_record_path(Path(), unit))):
        with atomic_path(dst / rel) as tmp:
            shutil.copyfile(src / rel, tmp)


def _stages(units: Iterable[Unit]) -> dict[str, list[Unit]]:
    stages: dict[str, list[Unit]] = {}
    keys: set[tuple[str, str]] = set()
    for u in units:
        if (u.stage, u.key) in keys:
            raise ValueError(f"two units share the key {u.stage}/{u.key}")
        keys.add((u.stage, u.key))
        stages.setdefault(u.stage, []).append(u)
    return stages


def run(study: Study, out: str | Path, seeds: int = 1, ray_address: str | None = None, progress: bool = True,
        log: Callable[[str], None] | None = None, jobs: int = 1, keep: str | Path | None = None,
        accept_data: str | None = None) -> Report:  # fmt: skip
    """Run ``study`` into ``out`` for ``seeds`` seeds (see the module docstring), ``jobs`` units at once in local
    worker processes (``ray_address``: as Ray tasks instead), keeping finished units in ``keep`` too (and restoring
    from it those ``out`` lacks), taking data of digest ``accept_data`` as the record's (:func:`check_manifest`);
    returns the report as written (its Markdown with the wall times, its JSON with the runner's ``"runner"`` entry:
    seeds and wall times)."""
    from tqdm import tqdm

    say = log or tqdm.write
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ValueError(f"seeds must be a positive integer, got {seeds!r}")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    if jobs > 1 and ray_address is not None:
        raise ValueError("jobs and ray_address exclude each other: Ray places the units itself")
    out = Path(out)
    keep = None if keep is None else Path(keep)
    if keep is not None and keep.resolve() == out.resolve():
        raise ValueError(f"keep must be another folder than out ({out})")
    ray = import_ray() if ray_address is not None else None
    settings = _jsonable(study.settings())
    folders = (out,) if keep is None else (out, keep)
    for folder in folders:
        check_manifest(folder, study.name, settings)
    seed_list = study.seed_list(seeds)
    units = study.units(seed_list)
    stages = _stages(units)
    note = study.announce(seed_list)
    if note:
        say(note)
    t0 = time.perf_counter()
    study.output = out  # where prepare may keep derived data (e.g. a cache) beside the units' files
    data = _jsonable(study.prepare(say, progress))
    for folder in folders:
        check_manifest(folder, study.name, settings, data, accept_data)
    for folder in folders:
        write_atomic(folder / MANIFEST, {"study": study.name, "settings": settings, "data": record_data(folder, data)})
    if ray is not None and not ray.is_initialized():
        ray.init(address=ray_address)
    records: dict[str, dict[str, Any]] = {}
    timing: dict[str, dict[str, Any]] = {}
    for stage, todo in stages.items():
        bar = tqdm(total=len(todo), desc=f"{study.name}: {stage}", unit="unit", disable=not progress)
        pending = []
        for unit in todo:
            record = _finished(study, out, unit)
            kept = None if keep is None else _finished(study, keep, unit)
            if record is None and kept is not None:
                _copy_unit(study, keep, out, unit)
                record = kept
                say(f"{unit.key}: restored from {keep}")
            if record is None:
                pending.append(unit)
                continue
            if keep is not None and kept is None:
                _copy_unit(study, out, keep, unit)
            records[unit.key] = record
            timing[unit.key] = {"stage": stage, "wall_s": record["wall_s"], "kept": True}
            say(f"{unit.key}: kept from {_record_path(out, unit)}")
            bar.update()

        def finish(unit: Unit, result: dict[str, Any], wall: float) -> None:
            record = {"stage": unit.stage, "key": unit.key, "seed": unit.seed, "params": dict(unit.params),
                      "result": result, "wall_s": wall}  # fmt: skip
            write_atomic(_record_path(out, unit), _jsonable(record))
            if keep is not None:
                _copy_unit(study, out, keep, unit)
            records[unit.key] = _jsonable(record)
            timing[unit.key] = {"stage": stage, "wall_s": wall, "kept": False}
            line = study.describe(unit, result)
            say(f"{unit.key}: {line + '; ' if line else ''}{wall:.0f} s")
            bar.update()

        if ray is None and (jobs == 1 or len(pending) < 2):
            for unit in pending:
                finish(unit, *_execute(study, unit, str(out), progress))
        elif ray is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor, as_completed

            ctx = multiprocessing.get_context("spawn")  # no forked copies of numba's or torch's thread pools
            with ProcessPoolExecutor(min(jobs, len(pending)), mp_context=ctx) as pool:
                futures = {pool.submit(_execute, study, unit, str(out.resolve()), False): unit for unit in pending}
                for future in as_completed(futures):
                    finish(futures[future], *future.result())
        else:
            task = ray.remote(_execute)
            refs = {task.options(num_cpus=unit.cpus).remote(study, unit, str(out.resolve()), False): unit
                    for unit in pending}  # fmt: skip
            while refs:
                done, _ = ray.wait(list(refs), num_returns=1)
                for ref in done:
                    finish(refs.pop(ref), *ray.get(ref))
        bar.close()
    records = {u.key: records[u.key] for u in units}
    report = study.report(records, out, seed_list)
    wall = time.perf_counter() - t0
    report.data["runner"] = {"seeds": seed_list, "wall_s": wall, "units_s": sum(t["wall_s"] for t in timing.values()),
                             "units": {u.key: timing[u.key] for u in units}}  # fmt: skip
    text = report.markdown.rstrip("\n") + "\n\n" + "\n".join(wall_time_lines(report.data["runner"], study.own_wall_times))
    write_atomic(out / report.md_name, text + "\n")
    write_atomic(out / report.json_name, _jsonable(report.data))
    if report.figures:
        import matplotlib

        matplotlib.use("Agg")
        for name, draw in report.figures.items():
            with atomic_path(out / name) as tmp:
                draw(tmp)
    report.markdown = text
    return report


def wall_time_lines(runner: Mapping[str, Any], totals_only: bool = False) -> list[str]:
    """The wall-time section: every unit's time (kept units: the time of the run that made them) and in all.

    >>> r = {"wall_s": 90.0, "units_s": 150.0, "units": {"a_s0": {"stage": "train", "wall_s": 150.0, "kept": True}}}
    >>> wall_time_lines(r)[-1]
    'Units in all: 2.5 min of wall time (0.04 h); this run: 1.5 min.'
    """
    total = f"Units in all: {runner['units_s'] / 60:.1f} min of wall time ({runner['units_s'] / 3600:.2f} h); this run: {runner['wall_s'] / 60:.1f} min."
    if totals_only:
        return [total]
    lines = ["## Wall time", "", "| unit | stage | wall time [min] | |", "|---|---|---|---|"]
    for key, t in runner["units"].items():
        lines.append(f"| {key} | {t['stage']} | {t['wall_s'] / 60:.1f} | {'kept' if t['kept'] else 'this run'} |")
    return lines + ["", total]


# -- the command line ------------------------------------------------------------------------------------------
def size_arg(text: str) -> tuple[int, int]:
    """An argparse type: ``WxH`` as ``(W, H)``, two positive integers.

    >>> size_arg("320x240")
    (320, 240)
    """
    from fog_gym.checks import parse_resolution

    try:
        return parse_resolution(tuple(int(v) for v in text.lower().split("x")))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH, two positive integers such as 320x240, got {text!r}") from None


def build_parser(study: type[Study]) -> argparse.ArgumentParser:
    """The study's options and the runner's: ``--out``, ``--seeds``, ``--smoke``, ``--ray``, ``--jobs``."""
    import textwrap

    text = "\n".join(textwrap.fill(line, 100) for line in study.description.split("\n"))
    parser = argparse.ArgumentParser(prog=study.command, description=text,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    study.add_arguments(parser)
    runner = parser.add_argument_group("runner (every study)")
    runner.add_argument("--out", type=Path, default=study.default_out,
                        help=f"output folder; run again to resume (default {study.default_out})")
    runner.add_argument("--seeds", type=int, default=1,
                        help="seeds per unit; tables give the mean and 95 %% CI across seeds (default 1)")
    runner.add_argument("--smoke", action="store_true", help=study.smoke_help)
    runner.add_argument("--ray", metavar="ADDRESS", default=None,
                        help="run units as Ray tasks on this cluster (the ray extra; --out on shared storage)")
    runner.add_argument("--jobs", type=int, default=1,
                        help="run up to N units of a stage at once in local worker processes (same results; "
                             "default 1)")
    runner.add_argument("--keep", type=Path, default=None, metavar="DIR",
                        help="also keep every finished unit (record and files) in DIR, a folder to commit or sync, "
                             "and restore from it the units --out lacks: a study that spans sessions or machines")
    runner.add_argument("--accept-data", metavar="DIGEST", default=None,
                        help="take data of this content digest as the study record's: the same dataset regenerated "
                             "on another machine, whose bytes differ in floating-point last bits (the refusal names "
                             "the digest; the record keeps both)")
    return parser


def main(study: type[Study], argv: Sequence[str] | None = None) -> int:
    """The command of a study: parse, refuse bad options (usage errors, exit status 2) and a folder of other
    settings or a missing Ray (``fog-gym <command>: <message>``, exit status 1) before any work, run, print."""
    parser = build_parser(study)
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    if args.jobs < 1:
        parser.error("--jobs must be >= 1")
    if args.jobs > 1 and args.ray is not None:
        parser.error("--jobs and --ray exclude each other (Ray places the units itself)")
    try:
        instance = study.from_args(args)
    except ValueError as e:
        parser.error(str(e))
    try:
        report = run(instance, args.out, seeds=args.seeds, ray_address=args.ray, jobs=args.jobs, keep=args.keep,
                     accept_data=args.accept_data)  # fmt: skip
    except (ValueError, FileNotFoundError, FileExistsError) as e:
        raise SystemExit(f"{study.command}: {e}") from None
    print(report.markdown)
    files = [report.md_name, report.json_name, *report.figures]
    print(f"\nwrote {', '.join(files)} to {args.out} in {report.data['runner']['wall_s'] / 60:.1f} min")
    return 0
