"""The names of the environment's model choices (the ``environment.*`` parameters' values), in a module
of their own so that the parameter schemas can name them without importing the models (the IGRF's
reader brings pandas, ~1 s of import in every node that validates parameters)."""
from __future__ import annotations

ORBIT_KINDS = ('circular', 'tle')
MAGNETIC_MODELS = ('igrf', 'dipole')
SHADOW_MODELS = ('cylindrical', 'conical')
# The span of the IGRF-14 coefficient file (ppigrf's IGRF14.shc: 1900.0-2030.0): an epoch outside it
# is refused by the parameter check; magnetic.IgrfModel checks every time against the file it reads.
IGRF_YEARS = (1900, 2030)
