"""Studies, each a subpackage shaped like the nuScenes devkit's ``eval/detection`` (data / train / evaluate / report,
and ``study``, what the runner drives) and run by the one study runner (:mod:`~fog_gym.experiments.runner`: seeds
with 95 % CIs, resume, progress, wall times, the report; ``fog-gym <study>`` or ``python -m``): the paper's
Experiment 1 (:mod:`~fog_gym.experiments.detection3d`, ``fog-gym exp1``), Experiment 2
(:mod:`~fog_gym.experiments.defog`, ``fog-gym exp2``) and the RL benchmark (:mod:`~fog_gym.experiments.rl_bench`,
``fog-gym rl-bench``). Beside them the annotation audit (:mod:`~fog_gym.experiments.audit`, ``fog-gym audit``) and
the performance benchmarks (:mod:`~fog_gym.experiments.bench`, ``fog-gym bench``)."""
