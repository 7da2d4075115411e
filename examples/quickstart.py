"""Drive a few seconds of FogDrive-v0 and save the front camera, depth and semantic views.

Run: python examples/quickstart.py --help
"""

import argparse
from pathlib import Path

import cv2
import gymnasium as gym
import numpy as np

import fog_gym
from fog_gym.encoding import colorize_depth, colorize_semantic


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--town", choices=fog_gym.TOWNS, default="highway")
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--out", type=Path, default=Path("out/quickstart"))
    args = parser.parse_args()

    env = gym.make("FogDrive-v0", town=args.town, resolution=(640, 480), cameras=["CAM_FRONT"])
    obs, info = env.reset(seed=0)
    for _ in range(args.steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            obs, info = env.reset()
    args.out.mkdir(parents=True, exist_ok=True)
    row = np.concatenate(
        [obs["CAM_FRONT"], colorize_depth(obs["CAM_FRONT_DEPTH"]), colorize_semantic(obs["CAM_FRONT_SEM"])], axis=1
    )
    cv2.imwrite(str(args.out / "front.png"), row[..., ::-1])
    print("wrote", args.out / "front.png")


if __name__ == "__main__":
    main()
