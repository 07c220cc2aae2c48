"""Node types: thin adapters over flowmc.motion and flowmc.devices, one module per area.

Each module declares its types with ``@register``. ``flowmc.plugins`` imports every module of
this package to build the default registry; a module that fails to import is recorded there,
not fatal: graphs that do not use its types still run, and the failure is shown where a type
is missing.

``BUILT_IN`` names each module's type ids, so a process finds the module of a type without reading
or importing the others (tests/core/test_plugins.py checks it against the modules).
"""

BUILT_IN: dict[str, tuple[str, ...]] = {
    "basic": ("basic.number", "basic.bool", "basic.text", "basic.add", "basic.subtract", "basic.multiply",
              "basic.divide", "basic.compare", "basic.ratio", "basic.check", "basic.report"),
    "device_log": ("device.log_report",),
    "devices": ("machine", "device.preflight", "device.card_output", "device.home", "device.jog", "device.io_now",
                "device.wait_input"),
    "gcode": ("path.gcode_in", "path.gcode_out"),
    "interpolators": ("interp.point_by_point", "interp.dda", "interp.linkage_table"),
    "linuxcnc": ("device.linuxcnc_compare",),
    "nurbs_profiles": ("interp.nurbs", "interp.time_division"),
    "path_measure": ("path.measure",),
    "path_ops": ("path.image_contour", "path.tool_offset", "path.pocket", "path.translate", "path.rotate",
                 "path.scale", "path.mirror", "path.join"),
    "path_sources": ("path.segment_table", "path.polyline", "path.nurbs"),
    "path_state": ("path.set_state", "path.approach"),
    "planning": ("plan.lookahead", "plan.stop_and_go", "plan.metrics"),
    "signals": ("device.digital_io", "device.pwm", "device.analog"),
    "structures": ("struct.for", "struct.while", "struct.case"),
    "subgraph": ("subgraph",),
    "vector": ("path.vector_in",),
    "view": ("view.view3d",),
}
