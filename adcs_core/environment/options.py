"""The names of the environment's model choices (the ``environment.*`` parameters' values), in a module
of their own so that the parameter schemas can name them without importing the models (the IGRF's
reader brings pandas, ~1 s of import in every node that validates parameters)."""
from __future__ import annotations

ORBIT_KINDS = ('circular', 'tle')
MAGNETIC_MODELS = ('igrf', 'dipole')
SHADOW_MODELS = ('cylindrical', 'conical')
