"""``python -m fog_gym.experiments.bench`` = ``fog-gym bench``."""

from fog_gym.experiments.bench.suite import main

if __name__ == "__main__":
    raise SystemExit(main())
