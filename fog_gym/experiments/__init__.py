"""Studies: the paper's Experiment 1 (:mod:`fog_gym.experiments.detection3d`), Experiment 2
(:mod:`fog_gym.experiments.defog`) and the annotation audit (:mod:`fog_gym.experiments.audit`)."""
