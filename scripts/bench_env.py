#!/usr/bin/env python
"""Developer shortcut for ``python -m fog_gym.experiments.bench.env``: per-stage timing of FogDrive-v0 against bare highway-env.
See its ``--help``."""

from fog_gym.experiments.bench.env import main

if __name__ == "__main__":
    raise SystemExit(main())
