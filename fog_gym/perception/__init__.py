"""Perception on fogged sensor data: perceived objects (:mod:`fog_gym.perception.objects`) and the rule-based
driver. The dehazers moved to :mod:`fog_gym.dehaze` (tools for any image)."""
