#!/usr/bin/env python
"""Developer shortcut for ``python -m fog_gym.experiments.bench.dataset``: the recorder against the PNG-encoder bound, fog-gym generate.
See its ``--help``."""

from fog_gym.experiments.bench.dataset import main

if __name__ == "__main__":
    raise SystemExit(main())
