"""RL glue: Stable-Baselines3 (:mod:`fog_gym.rl.sb3`, the ``rl`` extra) and Minari offline-RL datasets
(:mod:`fog_gym.rl.minari`, the ``minari`` extra). The RL presets themselves are environments
(:mod:`fog_gym.envs.presets`); curricula are :mod:`fog_gym.fog.curriculum`.
"""
