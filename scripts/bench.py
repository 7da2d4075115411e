#!/usr/bin/env python
"""Developer shortcut for ``python -m fog_gym.experiments.bench.suite``: every benchmark in one run (= fog-gym bench).
See its ``--help``."""

from fog_gym.experiments.bench.suite import main

if __name__ == "__main__":
    raise SystemExit(main())
