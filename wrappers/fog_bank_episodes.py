"""``FogBankEpisodes``: a new fog bank on the road ahead at every reset (the ``FogDriveRLFogBank-v0`` preset)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from fog_gym.fog.banks import BankConfig, bank_rng


class FogBankEpisodes(gym.Wrapper):
    """Draws a fog bank (:class:`~fog_gym.fog.banks.BankConfig`) at every ``reset`` and puts it in force for that
    episode through the in-place :class:`~fog_gym.wrappers.FogWrapper` below (its ``set_fog``). ``reset(seed=s)``
    draws from ``s`` (the same seed, the same bank); an unseeded reset continues the wrapper's generator.
    ``info["fog"]`` describes the episode's bank (the fog wrapper's field record).

    >>> import fog_gym
    >>> from fog_gym.wrappers import FogWrapper
    >>> from fog_gym.fog.fields import FogBank
    >>> base = FogWrapper(fog_gym.FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT"]), FogBank(50.0, 200.0, 100.0))
    >>> env = FogBankEpisodes(base)
    >>> a, b = env.reset(seed=3)[1]["fog"], env.reset(seed=3)[1]["fog"]
    >>> a == b, a["type"], 140.0 <= a["start"] <= 340.0
    (True, 'FogBank', True)
    """

    def __init__(self, env: gym.Env, banks: BankConfig | None = None) -> None:
        banks = BankConfig() if banks is None else banks
        if not isinstance(banks, BankConfig):
            raise ValueError(f"banks must be a fog_gym.fog.banks.BankConfig, got {banks!r}")
        try:
            env.get_wrapper_attr("set_fog")
        except AttributeError:
            raise ValueError("FogBankEpisodes wraps an env with an in-place FogWrapper (one that has set_fog)") from None
        super().__init__(env)
        self.banks = banks
        self._rng: np.random.Generator | None = None
        self.bank = None  # the bank of the current episode

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None or self._rng is None:
            self._rng = bank_rng(seed)
        self.bank = self.banks.draw(self._rng)
        self.env.get_wrapper_attr("set_fog")(self.bank)
        return self.env.reset(seed=seed, options=options)
