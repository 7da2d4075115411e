"""Perception on fogged sensor data: dehazers (:mod:`fog_gym.perception.dehaze`: Dark Channel Prior, the
Koschmieder oracle; :mod:`fog_gym.perception.aodnet`: AOD-Net, the ``torch`` extra)."""
