"""The package version, in a module of its own so that modules low in the import order
(the store's config hash, the Dataset's provenance) need not import the package's face.
Keep it equal to ``version`` in ``pyproject.toml``."""

__version__ = "0.1.0"
