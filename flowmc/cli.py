"""The ``flowmc`` command: run graphs headless, validate them, list node types, print the schema, sweep.

Exit codes: 0 success, 1 the run failed (or a tool is missing), 2 the graph or an argument is invalid,
130 a job stopped by Ctrl-C (a controlled stop).
Every problem is one line on stderr; no tracebacks (set FLOWMC_DEBUG=1 to see them).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable

from flowmc.errors import FlowmcError, GraphError, UsageError, printable

__all__ = ["main", "build_parser"]

EXIT_OK, EXIT_FAILED, EXIT_INVALID, EXIT_INTERRUPTED = 0, 1, 2, 130


def _err(line: str) -> None:
    """One message to stderr; text quoted from files (a terminal escape in a param) shows escaped."""
    print("\n".join(printable(part) for part in line.split("\n")), file=sys.stderr)


# ---------------------------------------------------------------- values from the command line

def _split_assignment(item: str, option: str) -> tuple[str, str]:
    key, sep, value = item.partition("=")
    if not sep or not key:
        raise UsageError(f"{option} {item!r}: expected NAME=VALUE")
    return key.strip(), value


def apply_sets(graph: Any, sets: list[str], registry: Any) -> None:
    """``--set NODE.PARAM=VALUE``: change stored params; unknown nodes or params are errors."""
    from flowmc.settings import param_target  # dataclasses and the settings' rules: only when asked

    for item in sets:
        name, text = _split_assignment(item, "--set")
        what = f"--set {name}"
        if "." not in name:
            raise UsageError(f"{what}: expected NODE.PARAM=VALUE")
        target = param_target(graph, name, what, registry)
        target.apply(graph, target.parse(text, what), {})


def parse_inputs(graph: Any, items: list[str]) -> dict[str, Any]:
    from flowmc.settings import input_target

    values: dict[str, Any] = {}
    for item in items:
        name, text = _split_assignment(item, "--input")
        what = f"--input {name}"
        target = input_target(graph, name, what)
        target.apply(graph, target.parse(text, what), values)
    return values


# ---------------------------------------------------------------- output

def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def write_json_atomic(path: Path, data: Any) -> None:
    from flowmc.fileio import write_atomic

    text = json.dumps(_json_safe(data), indent=2, ensure_ascii=False) + "\n"
    write_atomic(path, text, what="results file", error=FlowmcError)


def _progress_printer(total: int) -> Callable[[Any], None]:
    count = 0
    shown = [0.0]  # when an iteration line was last printed: loops say where they are about once a second

    def show(event: Any) -> None:
        nonlocal count
        if event.kind in ("queued", "running"):
            return
        if event.kind == "iteration":
            k, of = event.iteration or (0, None)
            if k == 1 or k == of or time.monotonic() - shown[0] >= 1.0:
                shown[0] = time.monotonic()
                _err(f"        {event.node_id}: {event.message}")
            return
        if event.kind == "log":
            _err(f"        {event.node_id}: {event.message}")
            return
        count += 1
        line = f"[{count:>{len(str(total))}}/{total}] {event.node_id:<20} {event.kind}"
        if event.kind in ("done", "failed") and event.duration is not None:
            line += f"  {event.duration * 1000:.1f} ms"
        if event.message and event.kind != "log":
            line += f"  {event.message}"
        _err(line)

    return show


def _print_issues(where: str, issues: list) -> None:
    _err(f"{where}: graph is invalid ({len(issues)} problem{'s' if len(issues) != 1 else ''}):")
    for issue in issues:
        _err(f"  {issue.message}")


# ---------------------------------------------------------------- commands

def _registry(args: argparse.Namespace) -> Any:
    """The default registry, with the node folders given by ``--nodes``."""
    from flowmc.plugins import add_node_folder, default_registry

    registry = default_registry()
    for folder in getattr(args, "nodes", None) or []:
        if not Path(folder).is_dir():
            raise UsageError(f"--nodes {folder}: not a folder")
        add_node_folder(registry, folder)
    return registry


def cmd_run(args: argparse.Namespace) -> int:
    import flowmc

    graph = flowmc.load(args.file)
    registry = _registry(args)
    apply_sets(graph, args.set, registry)
    inputs = parse_inputs(graph, args.input)
    runtime = flowmc.Runtime(registry)
    plan = runtime.plan(graph)
    if plan.issues:
        _print_issues(args.file, plan.issues)
        return EXIT_INVALID
    if not args.quiet:
        runtime.subscribe(_progress_printer(len(plan.order)))
    result = runtime.run(plan, inputs)  # device nodes prepare their jobs; nothing moves yet
    console = None
    if result.ok and result.jobs:  # ``flowmc run`` is the explicit Start on the command line
        from flowmc.cli_jobs import JobConsole

        console = JobConsole(quiet=args.quiet)
        result = console.start(runtime, result, _start_options(args, result))
    if args.out:
        write_json_atomic(Path(args.out), {"graph": str(args.file), **result.summary()})
    if args.snapshot:
        from flowmc.runtime.views import write_snapshots

        for written in write_snapshots(result, plan, runtime, args.snapshot):
            print(f"3D view: {written}", file=sys.stderr)
    for name, value in result.outputs.items():
        print(f"{name} = {json.dumps(_json_safe(flowmc.runtime.summarize(value)))}")
    if console is not None and console.interrupted:
        for line in console.where_stopped():
            _err(f"stopped by Ctrl-C: {line}")
        return EXIT_INTERRUPTED
    if not result.ok:
        for message in result.errors:
            _err(f"error: {message}")
        return EXIT_FAILED
    return EXIT_OK


def _start_options(args: argparse.Namespace, prepared: Any) -> dict[str, Any]:
    """The job runners' options from ``--realtime``, ``--speed``, ``--start-at``/``--start-line``,
    ``--optional-stop`` and the overrides."""
    options: dict[str, Any] = {"pace": "realtime" if args.realtime else "instant", "speed": args.speed,
                               "optional_stop": bool(args.optional_stop)}
    for name in ("feed", "rapid", "spindle"):
        if getattr(args, name) is not None:
            options[name] = getattr(args, name)
    for flag, key, what in (("--start-at", "start_at", "SEGMENT"), ("--start-line", "start_line", "LINE")):
        given = getattr(args, key)
        if not given:
            continue
        node, _, number = given.rpartition(":")
        programs = [n for n, job in prepared.jobs.items() if getattr(job, "operation", "") == "program"]
        if not node:
            if len(programs) != 1:
                raise UsageError(f"{flag} {given}: say which job, NODE:{what} (program jobs: "
                                 f"{', '.join(programs) or 'none'})")
            node = programs[0]
        if node not in programs:
            raise UsageError(f"{flag} {given}: {node!r} is not a program job (program jobs: "
                             f"{', '.join(programs) or 'none'})")
        try:
            options[key] = {node: int(number)}
        except ValueError:
            raise UsageError(f"{flag} {given}: the {what.lower()} is a number from 1") from None
    return options


def cmd_validate(args: argparse.Namespace) -> int:
    from flowmc.graph import load
    from flowmc.runtime.context import Site
    from flowmc.runtime.schedule import make_plan  # as Runtime.plan does, without the executor: nothing runs

    graph = load(args.file)
    plan = make_plan(graph, Site.for_graph(graph.base_dir, graph.path), _registry(args))
    if plan.issues:
        _print_issues(args.file, plan.issues)
        return EXIT_INVALID
    print(f"{args.file}: ok, {len(plan.order)} nodes; order: {', '.join(plan.order)}")
    return EXIT_OK


def _port_line(kind: str, port: dict[str, Any]) -> str:
    types = port.get("type") or " or ".join(port["types"])
    text = f"    {kind:<5} {port['name']}: {types}"
    if kind != "out" and not port["required"]:
        text += f" = {json.dumps(port['default'])}"
    return text + (f"  ({port['doc']})" if port["doc"] else "")


def cmd_nodes(args: argparse.Namespace) -> int:
    registry = _registry(args)
    described = registry.describe_all(Path.cwd())
    if args.json:
        print(json.dumps(described, indent=2))
    else:
        for d in described:
            print(f"{d['type_id']}  [{d['category']}] {d['title']}{'' if d['pure'] else '  (not cached)'}: {d['description']}")
            for port in d["inputs"]:
                print(_port_line("in", port))
            for port in d["param_inputs"]:
                print(_port_line("param", port))
            wired = {p["name"] for p in d["param_inputs"]}
            for name, prop in d["params_schema"].get("properties", {}).items():
                if name not in wired:
                    default = f" = {json.dumps(prop['default'])}" if "default" in prop else ""
                    print(f"    param {name}: {prop.get('type', 'value')}{default}")
            for port in d["outputs"]:
                print(_port_line("out", port))
    for where, error in registry.failures.items():
        _err(f"warning: {where} failed to load: {error}")
    return EXIT_OK


def cmd_schema(args: argparse.Namespace) -> int:
    from flowmc.graph import json_schema

    print(json.dumps(json_schema(), indent=2))
    return EXIT_OK


def cmd_serve(args: argparse.Namespace) -> int:
    """The editor, composed here: the UI gets the registry (with the --nodes folders) and one device
    session to share."""
    from flowmc.devices.session import DeviceSession
    from flowmc.ui.app import serve_main

    _registry(args)
    return serve_main(args, devices=DeviceSession())


def _graph_values(file: str, registry: Any) -> tuple[Any, Any, Any, Any]:
    """The last Path and Machine the graph produces, and its look-ahead plan and that node's params if it
    has one."""
    import flowmc
    from flowmc.motion.trajectory import Trajectory

    graph = flowmc.load(file)
    result = flowmc.Runtime(registry).run(graph)
    if not result.ok:
        raise GraphError("the graph failed: " + "; ".join(result.errors), where=file)
    paths, machines = result.values_of("Path"), result.values_of("Machine")
    if not paths:
        raise GraphError("the graph produces no Path to compare", where=file)
    plan = plan_params = None
    for node in graph.nodes:
        trajectory = result.nodes[node.id].outputs.get("trajectory") if node.id in result.nodes else None
        if node.type == "plan.lookahead" and isinstance(trajectory, Trajectory):
            plan, plan_params = trajectory, node.params or {}
    return paths[-1][2], machines[-1][2] if machines else None, plan, plan_params


def cmd_compare(args: argparse.Namespace) -> int:
    """Print flowmc's plan of the graph's path beside what LinuxCNC executed for it, set up alike
    (or, with --as-planned, the graph's own look-ahead plan as it is)."""
    from flowmc.devices.linuxcnc.compare import Settings, compare_path

    path, machine, plan, plan_params = _graph_values(args.graph, _registry(args))
    if args.as_planned and plan is not None:
        profile = plan_params.get("profile", "trapezoid")
        jerk = profile == "scurve" and plan_params.get("rule", "blend") == "blend"
        settings = Settings(profile, plan.period, float(plan_params.get("tolerance", 0.05)), jerk)
        comparison = compare_path(path, machine, tolerance=args.tolerance, flowmc=plan, flowmc_settings=settings)
        source = "the graph's own look-ahead plan"
    else:
        comparison = compare_path(path, machine, tolerance=args.tolerance, profile=args.profile)
        source = "flowmc's look-ahead planner, set up like LinuxCNC"
    print(f"{args.graph}: {source} vs LinuxCNC (G64 P{args.tolerance:g})")
    print(comparison.text())
    return EXIT_OK


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run the graph over a grid, a table or a folder of files (``flowmc.sweep``)."""
    from flowmc.sweep.command import sweep_main

    return sweep_main(args, _registry(args))


def _sweep_arguments(p: argparse.ArgumentParser) -> None:
    """``flowmc sweep``'s options (docs/sweeps.md); flowmc.sweep checks the executor and device choices too."""
    p.add_argument("graph", help="graph file (*.flowmc.json)")
    what = p.add_argument_group("what to sweep (several axes give their product)")
    what.add_argument("--grid", action="append", default=[], metavar="TARGET=V1,V2,...",
                      help="values of a setting: node.param or an interface input name; numbers also as "
                           "start:stop:step (stop included)")
    what.add_argument("--over", action="append", default=[], metavar="TARGET=PATTERN",
                      help="every file a glob pattern matches, e.g. gcode.file=programs/*.ngc")
    what.add_argument("--table", metavar="variants.csv", help="a CSV table: a header of targets, one variant per row")
    how = p.add_argument_group("where it runs")
    how.add_argument("--executor", choices=("local", "dask"), default="local",
                     help="local: processes on this machine; dask: a Dask LocalCluster, or --scheduler")
    how.add_argument("--workers", type=int, metavar="N", help="worker processes (default: one per core)")
    how.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    how.add_argument("--ship", action=argparse.BooleanOptionalAction, default=None,
                     help="send the graph's folder to the workers (default: only with --scheduler)")
    how.add_argument("--batch", type=int, metavar="N", help="variants per task (default: about 8 tasks per worker)")
    how.add_argument("--devices", choices=("refuse", "sim"), default="refuse",
                     help="device nodes that drive hardware: refuse the sweep (default), or run them on the "
                          "simulated card")
    out = p.add_argument_group("results")
    out.add_argument("--out", metavar="DIR", help="results folder (default: GRAPH-STEM-sweep)")
    out.add_argument("--resume", action="store_true", help="skip the variants the results folder already holds")
    out.add_argument("--overwrite", action="store_true", help="start again in a results folder that holds rows")
    out.add_argument("--plot", metavar="OUT,...", help="outputs to plot (default: the numeric outputs)")
    out.add_argument("--against", metavar="SETTING,...", help="swept settings on the x axis (default: all)")
    out.add_argument("--pareto", metavar="A,B", help="two objectives for a Pareto front (minimised; max:NAME maximises)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def _plugin_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--nodes", action="append", default=[], metavar="DIR",
                   help="also load the node types in this folder's *.py files (repeatable)")
    p.add_argument("--memory-mb", type=float, metavar="MB",
                   help="memory budget for what one node may produce (default 256 MB, or FLOWMC_MEMORY_MB)")


def _run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="graph file (*.flowmc.json)")
    p.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE", help="override a stored param")
    p.add_argument("--input", action="append", default=[], metavar="NAME=VALUE", help="give an interface input")
    p.add_argument("--out", metavar="results.json", help="write per-node results and outputs as JSON")
    p.add_argument("--snapshot", metavar="DIR", help="write a PNG of every 3D View node's content into DIR")
    p.add_argument("-q", "--quiet", action="store_true", help="no per-node progress on stderr")
    jobs = p.add_argument_group("jobs (flowmc run is the explicit Start: device nodes run; Ctrl-C stops them, "
                                "exit 130)")
    jobs.add_argument("--realtime", action="store_true",
                      help="run the simulated card's jobs at the pace of the wall clock (default: at once)")
    jobs.add_argument("--speed", type=float, default=1.0, metavar="X",
                      help="with --realtime: this many times faster than real time (default 1)")
    jobs.add_argument("--start-at", metavar="[NODE:]SEGMENT",
                      help="start the program job from this segment (from 1): the machine state there is rebuilt "
                           "and the tool approaches safely")
    jobs.add_argument("--start-line", metavar="[NODE:]LINE",
                      help="start the program job at this G-code line (or the next line that moves), as --start-at")
    jobs.add_argument("--optional-stop", action="store_true", help="the program's M1 stops the job (as M0 does)")
    jobs.add_argument("--feed", type=float, metavar="PCT", help="feed override, 10-200 %% (default 100)")
    jobs.add_argument("--rapid", type=float, metavar="PCT", help="rapid override, 25, 50 or 100 %%")
    jobs.add_argument("--spindle", type=float, metavar="PCT", help="spindle override, 50-200 %%")


def _validate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="graph file (*.flowmc.json)")


def _nodes_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="machine-readable description")


def _serve_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", nargs="?", help="graph file to open (default: browse the current folder)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port to listen on (default: 8080)")


def _compare_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("graph", help="graph file whose last Path (and Machine, and look-ahead plan) is compared")
    p.add_argument("--with", dest="reference", choices=["linuxcnc"], default="linuxcnc",
                   help="the reference that runs the same program (default: linuxcnc)")
    p.add_argument("--tolerance", type=float, default=0.05, metavar="MM",
                   help="corner tolerance: G64 P for LinuxCNC, blend tolerance for flowmc (default: 0.05)")
    p.add_argument("--profile", choices=["trapezoid", "scurve"], default="trapezoid",
                   help="flowmc's profile (default: trapezoid, as LinuxCNC's planner; scurve is listed as a difference)")
    p.add_argument("--as-planned", action="store_true",
                   help="compare the graph's own look-ahead plan as it is, differences listed at the top")


# name -> (help, takes --nodes and --memory-mb, its own arguments, what runs it)
_COMMANDS: dict[str, tuple[str, bool, Callable[[argparse.ArgumentParser], None], Callable[..., int]]] = {
    "run": ("run a graph headless", True, _run_arguments, cmd_run),
    "validate": ("check a graph without running it", True, _validate_arguments, cmd_validate),
    "nodes": ("list every node type with its ports and params", True, _nodes_arguments, cmd_nodes),
    "schema": ("print the graph file JSON Schema", False, lambda p: None, cmd_schema),
    "serve": ("open the graph editor in the browser", True, _serve_arguments, cmd_serve),
    "compare": ("compare a graph's motion with LinuxCNC's", True, _compare_arguments, cmd_compare),
    "sweep": ("run a graph over many settings (a grid, a table, a folder of files) in parallel", True,
              _sweep_arguments, cmd_sweep),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; with ``command``, only that command's arguments are built (the others are
    listed, with their help): a cold ``flowmc validate`` does not build ``flowmc run``'s and ``flowmc
    sweep``'s options (benchmarks/cold_start.py)."""
    from flowmc import __version__

    parser = argparse.ArgumentParser(prog="flowmc", description="Dataflow graphs for motion control.")
    parser.add_argument("--version", action="version", version=f"flowmc {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (text, plugins, arguments, func) in _COMMANDS.items():
        p = sub.add_parser(name, help=text)
        if command is None or command == name:
            if plugins:
                _plugin_arguments(p)
            arguments(p)
            p.set_defaults(func=func)
    return parser


def _command_in(argv: list[str]) -> str | None:
    """The command ``argv`` names (the first word that is not an option: the top level's options take no
    value), or None when it names none that exists (the full parser then says what is wrong)."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in _COMMANDS else None


def _set_memory_budget(megabytes: float) -> None:
    import flowmc.budget as budget

    try:
        budget.configure(memory_mb=megabytes)
    except ValueError as exc:
        raise UsageError(f"--memory-mb: {exc}") from None


def main(argv: list[str] | None = None) -> int:
    # pydantic looks for its plugins (observers of every validation) by reading the entry points of every
    # installed distribution, on the first model a process builds: a tenth of a cold ``flowmc validate``'s
    # own time. flowmc's models are its file formats and node params, which nothing plugs into, so the
    # command goes without them unless PYDANTIC_DISABLE_PLUGINS is set (empty: load them all; README.md).
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(_command_in(argv)).parse_args(argv)
    try:
        if getattr(args, "memory_mb", None) is not None:
            _set_memory_budget(args.memory_mb)
        return args.func(args)
    except GraphError as exc:
        if exc.issues:
            _print_issues(exc.where or "graph", exc.issues)
        else:
            _err(f"error: {exc}")
        return EXIT_INVALID
    except UsageError as exc:
        _err(f"error: {exc}")
        return EXIT_INVALID
    except FlowmcError as exc:
        _err(f"error: {exc}")
        return EXIT_FAILED
    except BrokenPipeError:  # output piped into `head`
        sys.stdout = open(os.devnull, "w")
        return EXIT_OK
    except OSError as exc:
        _err(f"error: {exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}")
        return EXIT_FAILED
    except KeyboardInterrupt:
        _err("interrupted")
        return 130
    except Exception as exc:  # a bug: still one line, the traceback on request
        if os.environ.get("FLOWMC_DEBUG"):
            raise
        _err(f"internal error: {type(exc).__name__}: {exc} (set FLOWMC_DEBUG=1 for the traceback)")
        return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
