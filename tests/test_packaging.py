"""The built wheel works on its own: installed without ``-e`` into a fresh virtual environment, it makes a foggy
env, records a day/night pair of episodes and validates them with the installed ``fog-gym`` command, and its
benchmarks and studies run from the wheel (no source checkout)."""

import site
import subprocess
import sys
import textwrap
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
_WHEEL: list[Path] = []  # the wheel the fixture built

SCRIPT = textwrap.dedent(
    """
    import sys
    import gymnasium as gym
    import fog_gym, fog_gym.dataset, fog_gym.wrappers
    from fog_gym.wrappers import RecordFogDrive

    assert fog_gym.__file__.startswith(sys.prefix), fog_gym.__file__          # the wheel, not the source tree
    assert fog_gym.wrappers.__file__.startswith(sys.prefix), fog_gym.wrappers.__file__
    env = gym.make("FogDrive-v0", fog="dense", resolution=(32, 24))
    obs, info = env.reset(seed=0)
    obs, *_ = env.step(env.action_space.sample())
    assert obs["CAM_FRONT"].shape == (24, 32, 3) and info["fog"]["visibility_m"] == 50.0
    env.close()
    for tod in ("day", "night"):
        rec = RecordFogDrive(fog_gym.FogDriveEnv(time_of_day=tod, resolution=(32, 24), episode_seconds=0.2), "ds")
        rec.reset(seed=1)
        done = False
        while not done:
            _, _, term, trunc, _ = rec.step(1)
            done = term or trunc
        rec.close()
    print("ok", len(fog_gym.dataset.FogDrive("ds").sample))
    """
)


@pytest.fixture(scope="module")
def wheel_env(tmp_path_factory):
    """A fresh virtual environment with the built wheel installed without ``-e`` (dependencies from this
    interpreter's site-packages) and a work folder outside the repository; yields (python, fog-gym command, work)."""
    tmp_path = tmp_path_factory.mktemp("wheel")
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(ROOT)], check=True)
    (wheel,) = wheels.glob("fog_gym-*.whl")
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=False)
    python = env_dir / "bin" / "python"
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "-q", str(wheel)], check=True)
    # Dependencies come from this interpreter's site-packages, added as a plain path (a .pth line), so its
    # editable install of fog-gym (a .pth finder processed only for site dirs) is not picked up.
    purelib = next(env_dir.glob("lib/python*/site-packages"))
    (purelib / "zz_deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    work = tmp_path / "work"  # not the repository root, so the source tree is not importable
    work.mkdir()
    _WHEEL.append(wheel)
    return python, str(env_dir / "bin" / "fog-gym"), work


#: Libraries a user's environment shares with fog-gym: a requirement may bound them, never pin one release.
SHARED = ("torch", "numpy", "gymnasium", "opencv-python", "opencv-python-headless", "scipy", "matplotlib",
          "stable-baselines3", "pycocotools", "scikit-image", "scikit-learn", "ray")  # fmt: skip


def test_the_wheel_pins_no_release_of_a_library_users_share(wheel_env):
    """The built wheel's metadata: every requirement on torch, numpy, gymnasium, OpenCV, … is a range (so
    Ultralytics, mmdetection3d and the user's own torch can live beside fog-gym); torch is required only by extras."""
    import re
    import zipfile

    with zipfile.ZipFile(_WHEEL[-1]) as z:
        meta = z.read(next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))).decode()
    requires = [line.split(":", 1)[1].strip() for line in meta.splitlines() if line.startswith("Requires-Dist:")]
    assert requires
    pinned = []
    for req in requires:
        name = re.match(r"[A-Za-z0-9_.-]+", req).group(0).lower()
        if name in SHARED and re.search(r"==\s*[0-9]", req.split(";")[0]):
            pinned.append(req)
    assert pinned == []
    torch = [r for r in requires if re.match(r"torch\b", r)]
    assert torch and all("extra ==" in r and ">=" in r and "<" in r for r in torch), torch


def test_the_wheel_imports_from_itself_and_every_command_answers_help(wheel_env):
    python, fog_gym_cmd, work = wheel_env
    check = ("import sys, fog_gym, fog_gym.wrappers, fog_gym.experiments.bench.fog; "
             "assert fog_gym.__file__.startswith(sys.prefix), fog_gym.__file__; "
             "assert fog_gym.wrappers.__file__.startswith(sys.prefix), fog_gym.wrappers.__file__; print('ok')")  # fmt: skip
    out = subprocess.run([str(python), "-c", check], cwd=work, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-3000:]
    for command in ("bench", "exp1", "exp2", "rl-bench", "generate", "validate", "export"):
        helped = subprocess.run([fog_gym_cmd, command, "--help"], cwd=work, capture_output=True, text=True)
        assert helped.returncode == 0 and helped.stdout.startswith(f"usage: fog-gym {command}"), helped.stderr[-2000:]


@pytest.mark.slow
def test_the_wheel_records_validates_and_benchmarks_without_a_checkout(wheel_env):
    """Slow: a fresh install compiles every numba kernel once (≈ 1.5 min on 2 cores)."""
    python, fog_gym_cmd, work = wheel_env
    out = subprocess.run([str(python), "-c", SCRIPT], cwd=work, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split()[-2:] == ["ok", "6"]  # 2 scenes × (reset + 2 steps)
    val = subprocess.run([fog_gym_cmd, "validate", "ds"], cwd=work, capture_output=True, text=True)
    assert val.returncode == 0, val.stdout + val.stderr
    assert val.stdout.strip().endswith("valid")
    bench = subprocess.run([str(python), "-m", "fog_gym.experiments.bench.fog", "--quick"], cwd=work, capture_output=True,
                           text=True, timeout=900)  # fmt: skip
    assert bench.returncode == 0, bench.stderr[-3000:]
    assert "full paired frame" in bench.stdout and "CPUs, numba" in bench.stdout


@pytest.mark.parametrize("package", ["fog_gym.dataset", "fog_gym.render", "fog_gym.wrappers"])
def test_setup_discovers_every_subpackage(package):
    out = subprocess.run([sys.executable, "-c", "import runpy, setuptools; setuptools.setup = lambda **kw: print("
                          "' '.join(kw['packages'])); runpy.run_path('setup.py')"], cwd=ROOT, capture_output=True, text=True)
    found = out.stdout.split()
    assert package in found
    folders = {p.parent for p in (ROOT / "fog_gym").rglob("__init__.py")} | {p.parent for p in (ROOT / "wrappers").rglob("__init__.py")}
    assert len(found) == len(folders)


def test_the_dev_install_carries_the_export_readers():
    """CI (./dev test) checks the exports with pycocotools and the nuScenes devkit: the dev extra holds the export
    extra, and ./dev installs the devkit without its numpy<2 pin (pyproject.toml says why)."""
    import re
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(extras["export"]) <= set(extras["dev"])
    assert re.search(r'pip_install "[^"]*" --no-deps "nuscenes-devkit==1\.2\.0"', (ROOT / "dev").read_text())
