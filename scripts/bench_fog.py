#!/usr/bin/env python
"""Developer shortcut for ``python -m fog_gym.experiments.bench.fog``: camera and LiDAR fog, the full paired fog frame.
See its ``--help``."""

from fog_gym.experiments.bench.fog import main

if __name__ == "__main__":
    raise SystemExit(main())
