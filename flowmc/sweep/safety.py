"""What a sweep lets device nodes do: a sweep never moves a machine.

A device node is a node type with a ``device`` param (``sim``, ``grbl:<port>``, ``linuxcnc``, ...).
Simulators (the simulated card ``sim``, the GRBL protocol simulator ``grbl-sim`` and LinuxCNC's
simulator ``linuxcnc``) run in a sweep. Any other device drives hardware, and the sweep's ``devices``
policy decides:

- ``refuse`` (the default): the sweep is refused before anything runs, naming the node;
- ``sim``: those nodes run on the simulated card instead (their ``device`` is set to ``sim`` in every
  variant), so the rows hold what the program would do, measured on the model of the card.

A device whose value cannot be known before the run (fed by a wire from another node), or is stored
inside a sub-graph file where ``sim`` cannot reach it, is refused under both policies.
LinuxCNC runs hold the ``linuxcnc`` host resource (LinuxCNC instances on one host collide), as do node
types that declare it in ``host_resources`` (the LinuxCNC comparison).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from flowmc.settings import UsageError

__all__ = ["POLICIES", "SIMULATORS", "DeviceUse", "device_uses", "SafetyPlan", "check_devices"]

POLICIES = ("refuse", "sim")
SIMULATORS = {"sim": (), "grbl-sim": (), "linuxcnc": ("linuxcnc",)}  # device name -> host resources it holds


@dataclass(frozen=True)
class DeviceUse:
    """A device node somewhere in the graph. ``where``: its id (``outer/inner`` inside sub-graphs);
    ``spec``: its device when the graph alone says (None: fed by a wire); ``source``: the top-level setting
    that decides it (``node.device`` or an interface input name; None when a sub-graph file stores it)."""

    where: str
    spec: str | None
    source: str | None
    resources: tuple[str, ...] = ()


def _default(cls: Any, name: str) -> Any:
    field = cls.Params.model_fields.get(name)
    return None if field is None or field.is_required() else field.get_default(call_default_factory=True)


def _port_value(node: Any, name: str, outer: Any) -> tuple[str, Any, str | None]:
    """How a node's param or port ``name`` gets its value: ("known", value, source), ("unknown", why, None)
    or ("unset", None, source) when nothing gives one (an inner node keeps its own)."""
    if name in node.sources:
        src_node, src_port = node.sources[name]
        return "unknown", f"fed by the wire from {src_node}.{src_port}", None
    if name in node.fed:
        return outer(node.fed[name])
    if node.raw_params.get(name) is not None:
        return "known", node.raw_params[name], None
    return "unset", None, None


def device_uses(plan: Any, prefix: str = "", outer: Any = None) -> list[DeviceUse]:
    """Every device node and every node holding a host resource, sub-graphs included (``spec`` is "" for
    a node with no device param)."""
    if outer is None:
        def outer(name: str) -> tuple[str, Any, str | None]:  # the top graph's interface inputs
            item = plan.iface_inputs[name][0]
            return ("known", item.default, name) if item.default is not None else ("unset", None, name)
    uses = []
    for node_id in plan.order:
        node = plan.nodes[node_id]
        where, top = prefix + node_id, not prefix
        if "device" in node.cls.Params.model_fields and node.binding is None:
            how, value, source = _port_value(node, "device", outer)
            if how == "unset":
                stored = node.raw_params.get("device")
                value = stored if stored is not None else _default(node.cls, "device")
            if top and source is None and how != "unknown":
                source = f"{node_id}.device"
            spec = None if how == "unknown" else str(value).strip()
            uses.append(DeviceUse(where, spec, source, tuple(node.cls.host_resources)))
        elif node.cls.host_resources:
            uses.append(DeviceUse(where, "", None, tuple(node.cls.host_resources)))
        if node.binding is not None:
            uses += device_uses(node.binding, where + "/", _inner_resolver(node, outer, top))
    return uses


def _inner_resolver(node: Any, outer: Any, top: bool) -> Any:
    """Values of a sub-graph's interface inputs: what the outer node is given for the same name."""
    def resolve(name: str) -> tuple[str, Any, str | None]:
        how, value, source = _port_value(node, name, outer)
        if top and source is None and how in ("known", "unset") and name in node.cls.Params.model_fields:
            source = f"{node.id}.{name}"  # a library node's scalar input is a param we can set
        return how, value, source
    return resolve


def _hardware(spec: str) -> bool:
    return bool(spec) and spec.partition(":")[0] not in SIMULATORS


@dataclass(frozen=True)
class SafetyPlan:
    """What the workers do: ``to_sim`` lists the settings set to ``sim`` in every variant; ``resources``
    the host resources every run holds."""

    to_sim: tuple[str, ...]
    resources: tuple[str, ...]
    notes: tuple[str, ...]


def check_devices(uses: list[DeviceUse], swept: dict[str, Iterable[Any]], policy: str) -> SafetyPlan:
    """Refuse (UsageError naming the node) or plan the sweep's device nodes. ``swept``: the values each swept
    setting takes (None: a variant that leaves it as the graph has it), so a device chosen by an axis is
    checked for every value it takes."""
    if policy not in POLICIES:
        raise UsageError(f"--devices {policy!r}: choose {' or '.join(POLICIES)}")
    to_sim: list[str] = []
    resources: dict[str, None] = {}
    notes = []
    for use in uses:
        if use.spec is None:
            raise UsageError(f"node {use.where!r}: its device is fed by a wire, so a sweep cannot know whether "
                             "it moves hardware; store the device in the node (or give it as an input)")
        given = list(swept.get(use.source or "", ()))
        specs = {str(v).strip() for v in given if v is not None}
        if not given or None in given:  # some variants keep the graph's own device
            specs.add(use.spec)
        hardware = sorted(s for s in specs if _hardware(s))
        if hardware and policy == "refuse":
            raise UsageError(f"node {use.where!r}: device {hardware[0]!r} moves hardware, and a sweep never "
                             "moves a machine; use a simulator (sim, grbl-sim, linuxcnc) or --devices sim")
        if hardware:
            if use.source is None:
                raise UsageError(f"node {use.where!r}: device {hardware[0]!r} is stored inside a sub-graph file, "
                                 "where --devices sim cannot reach it; give the sub-graph a device input")
            to_sim.append(use.source)
            notes.append(f"node {use.where!r}: {', '.join(hardware)} -> simulated card (--devices sim)")
            specs = {"sim"}
        for res in (*use.resources, *(r for s in specs for r in SIMULATORS.get(s.partition(":")[0], ()))):
            resources[res] = None
    return SafetyPlan(tuple(dict.fromkeys(to_sim)), tuple(resources), tuple(notes))
