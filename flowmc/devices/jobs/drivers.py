"""Which driver runs a job: the device's own (GRBL, LinuxCNC), or the simulated card's at the job's pace."""

from __future__ import annotations

from flowmc.errors import DeviceError

__all__ = ["driver_for"]


def driver_for(runner, card):
    """A driver with ``run() -> DeviceLog`` for this runner's job on ``card``."""
    from flowmc.devices.sim.card import SimCard

    if isinstance(card, SimCard):
        from flowmc.devices.jobs.sim_driver import SimInstant, SimStream

        return SimInstant(runner, card) if runner.pace == "instant" else SimStream(runner, card)
    from flowmc.devices.grbl import GrblCard
    from flowmc.devices.linuxcnc.card import LinuxCNCCard

    if isinstance(card, LinuxCNCCard) and runner.job.operation == "program":
        from flowmc.devices.jobs.linuxcnc_driver import LinuxCNCDriver

        _linuxcnc_can_run(runner)
        return LinuxCNCDriver(runner, card)
    from flowmc.devices.jobs.card_driver import InstantDriver

    if isinstance(card, GrblCard) and runner.job.operation == "program":
        from flowmc.devices.jobs.grbl_driver import GrblDriver

        return GrblDriver(runner, card)

    return InstantDriver(runner, card)


def _linuxcnc_can_run(runner) -> None:
    """Refuse what the LinuxCNC driver cannot pass on yet (its G-code is one line per setpoint, without
    the program's stops), rather than run straight through a tool change or a single-block request."""
    job = runner.job
    stops = [e for e in getattr(job.motion, "events", ()) if e.kind != "optional_pause" or runner.status.optional_stop]
    if stops:
        raise DeviceError(f"the {stops[0].what} at {job.where(stops[0].segment)} would not stop LinuxCNC: program "
                          "stops are not passed to it yet, so nothing was moved; remove the stop or run the job "
                          "on the simulated card or GRBL", where=job.name or "job")
    if runner.status.single_block:
        raise DeviceError("single block is not passed to LinuxCNC yet, so nothing was moved; start without it",
                          where=job.name or "job")
