"""What Experiments 1 and 2 share as studies: a FogDrive dataset at ``--root`` (generated first on request), a
config whose ``seed`` chooses the data and the first training seed, and the training options both take.

Example:
    >>> from types import SimpleNamespace
    >>> DatasetStudy("out/data", SimpleNamespace(seed=5)).seed_list(3)
    [5, 6, 7]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fog_gym.experiments.runner import Study


class DatasetStudy(Study):
    """A study of a detector trained and tested on the dataset at ``root``; ``generate`` scenes of ``seconds`` are
    written there first (``generate_options``: more arguments of :func:`fog_gym.generate.plan_scenes`)."""

    def __init__(self, root: str | Path, config: Any, generate: int = 0, seconds: float = 10.0,
                 gen_workers: int = 1, **generate_options: Any) -> None:  # fmt: skip
        if isinstance(generate, bool) or generate < 0 or gen_workers < 1 or not seconds > 0:
            raise ValueError(f"generate must be >= 0, gen_workers >= 1 and seconds > 0, got {generate}, {gen_workers}, {seconds}")
        self.root, self.config, self.generate, self.seconds = Path(root), config, generate, seconds
        self.gen_workers, self.generate_options = gen_workers, generate_options

    def settings(self) -> dict[str, Any]:
        return self.config.settings()

    def seed_list(self, k: int) -> list[int]:
        """Training seeds ``seed``, ``seed + 1``, …: every seed trains on the data ``seed`` chose."""
        return [self.config.seed + i for i in range(k)]

    def open_dataset(self, log: Callable[[str], None], progress: bool) -> Any:
        """Generate the dataset when asked to, then open it."""
        from fog_gym.dataset.access import FogDrive

        if self.generate:
            from fog_gym.generate import generate, plan_scenes

            t0 = time.perf_counter()
            plan = plan_scenes(self.generate, seed=self.config.seed, seconds=self.seconds, **self.generate_options)
            generate(self.root, plan, workers=self.gen_workers, progress=progress)
            log(f"generated {self.generate} scenes in {self.root} in {time.perf_counter() - t0:.0f} s")
        return FogDrive(self.root)

    @staticmethod
    def add_common_arguments(p: argparse.ArgumentParser, what: str, epochs: str, lr: float) -> None:
        """``--root``, the generation options and the training options both experiments take."""
        p.add_argument("--root", type=Path, required=True, help=f"FogDrive dataset root ({what})")
        p.add_argument("--generate", type=int, default=0, metavar="SCENES",
                       help="first generate a dataset of this many scenes into --root (must be empty)")
        p.add_argument("--seconds", type=float, default=10.0, help="scene length when generating (default 10 s)")
        p.add_argument("--gen-workers", type=int, default=1, help="worker processes when generating (default 1)")
        p.add_argument("--epochs", type=int, default=20, help=f"training epochs per {epochs} (default 20)")
        p.add_argument("--batch-size", type=int, default=16, help="batch size (default 16)")
        p.add_argument("--lr", type=float, default=lr, help=f"peak learning rate of the one-cycle schedule (default {lr:g})")
        p.add_argument("--every", type=int, default=2, help="use every n-th training sample of a scene (default 2: 5 Hz)")
        p.add_argument("--test-every", type=int, default=2, help="use every n-th test sample (default 2)")
        p.add_argument("--eval-every", type=int, default=1, help="evaluate after every n-th epoch and the last (default 1)")
        p.add_argument("--device", default="auto", help="torch device: auto (GPU when present), cpu, cuda")
        p.add_argument("--seed", type=int, default=0, help="seed of the data choice and of the first training seed (default 0)")

    @staticmethod
    def smoke_dataset(args: argparse.Namespace) -> None:
        """``--smoke``: generate 10 scenes unless ``--root`` already holds a dataset."""
        args.generate = args.generate or (0 if (args.root / "index").exists() else 10)
