"""``RecordFogDrive`` refuses what it cannot record as FogDrive before writing anything (the recorded layout itself
is tested in test_dataset.py)."""

import pytest

import fog_gym
from fog_gym.wrappers import RecordFogDrive

RES = (48, 36)


def test_record_refuses_partial_rigs_and_in_place_fog(tmp_path):
    with pytest.raises(ValueError, match="full FogDrive rig"):
        RecordFogDrive(fog_gym.FogDriveEnv(resolution=RES, cameras=["CAM_FRONT"]), tmp_path)
    with pytest.raises(ValueError, match="paired levels"):
        RecordFogDrive(fog_gym.wrappers.FogWrapper(fog_gym.FogDriveEnv(resolution=RES), "dense"), tmp_path)
