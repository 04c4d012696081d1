"""The package list, which pyproject.toml cannot express: sweep and every subpackage
setuptools finds under sweep/, and sweep.configs, which pyproject.toml maps to the
top-level configs/ folder ([tool.setuptools.package-dir]). ``packages.find`` does not
look at package-dir, so in pyproject.toml the list had to be written by hand, and a
subpackage missing from it was missing from every install (issue 36 §4). Everything
else is in pyproject.toml."""

from setuptools import find_packages, setup

setup(packages=[*find_packages(include=["sweep", "sweep.*"]), "sweep.configs"])
