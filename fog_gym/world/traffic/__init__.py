"""Traffic core: highway-env's O(N²) hot paths over structure-of-arrays, installed per env instance.

``accelerate(env)`` speeds up a highway-env environment in place while keeping its trajectories, rewards and
random draws identical to highway-env's own Python path (see ``fog_gym.world.traffic.core``).
"""

from fog_gym.world.towns import TRAFFIC_MODES
from fog_gym.world.traffic.core import SUPPORTED_ENVS, accelerate, is_accelerated

__all__ = ["SUPPORTED_ENVS", "TRAFFIC_MODES", "accelerate", "is_accelerated"]
