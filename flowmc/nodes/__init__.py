"""Node types: thin adapters over flowmc.motion and flowmc.devices, one module per area.

Each module declares its types with ``@register``. ``flowmc.plugins`` imports every module of
this package to build the default registry; a module that fails to import is recorded there,
not fatal: graphs that do not use its types still run, and the failure is shown where a type
is missing.
"""
