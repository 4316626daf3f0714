"""contopt: topology optimization of hyperelastic bodies in contact.

Nothing here changes global JAX state on import; entry points call
:func:`contopt.config.enable_x64` (and the CLI/tests enable the persistent
compilation cache) explicitly.
"""

__version__ = "0.1.0"
