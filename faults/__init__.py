"""Fault kinds, the injector that applies them to frame copies, and the engine of tick faults.

Importing the package registers the built-in kinds, family by family, in this order: the
order of ``faults.registry.FAULT_KINDS`` (and of the error messages that list them).
"""

# isort: off
from faults import link, cuts, node, sensing, adversary, energy  # noqa: F401  (each registers its kinds)
# isort: on
