#!/usr/bin/env python
"""Developer shortcut for ``python -m fog_gym.experiments.bench.sensors``: point sensors, ground truth, night vs day cameras.
See its ``--help``."""

from fog_gym.experiments.bench.sensors import main

if __name__ == "__main__":
    raise SystemExit(main())
