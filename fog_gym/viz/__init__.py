"""Pictures: figures that explain themselves (:mod:`fog_gym.viz.figures`: the demo's and the docs' sensor figures,
with titles, panel labels, colour bars and legends) and the Rerun viewer (:mod:`fog_gym.viz.viewer`, the ``viz``
extra)."""
