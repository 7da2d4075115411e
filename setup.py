"""Package discovery for setuptools; all metadata lives in pyproject.toml.

Every folder with an ``__init__.py`` under ``fog_gym/`` is a package, and the top-level ``wrappers/`` folder
(with its subfolders) installs as ``fog_gym.wrappers``, so a wheel cannot miss a subpackage.
"""

from setuptools import find_packages, setup

WRAPPERS = "wrappers"
packages = find_packages(include=["fog_gym", "fog_gym.*"])
packages += ["fog_gym." + p for p in find_packages(include=[WRAPPERS, WRAPPERS + ".*"])]

setup(packages=sorted(packages), package_dir={"fog_gym.wrappers": WRAPPERS})
