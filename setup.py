"""Package discovery for setuptools; all metadata lives in pyproject.toml.

Every folder with an ``__init__.py`` under ``fog_gym/`` is a package, so a wheel cannot miss a subpackage. The
top-level ``wrappers/`` folder is the ``fog_gym.wrappers`` package: ``fog_gym/wrappers`` is a symbolic link to it, so
imports, static tools and setuptools all find it at ``fog_gym/wrappers`` (the wheel holds the files themselves).
"""

from setuptools import find_packages, setup

setup(packages=sorted(find_packages(include=["fog_gym", "fog_gym.*"])))
