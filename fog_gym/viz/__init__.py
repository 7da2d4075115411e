"""Pictures: drawing (:mod:`fog_gym.viz.draw`: bird's-eye views, contact sheets, LiDAR panels, fog-level strips) and
the Rerun viewer (:mod:`fog_gym.viz.viewer`, the ``viz`` extra)."""
