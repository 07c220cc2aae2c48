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
    if runner.start_at is not None and runner.job.operation != "program":
        raise DeviceError(f"only a program starts at a segment, not a '{runner.job.operation}' job: nothing was moved",
                          where=runner.job.name or "job")
    from flowmc.devices.grbl import GrblCard
    from flowmc.devices.linuxcnc.card import LinuxCNCCard

    if isinstance(card, LinuxCNCCard) and runner.job.operation == "program":
        from flowmc.devices.jobs.linuxcnc_driver import LinuxCNCDriver

        return LinuxCNCDriver(runner, card)
    from flowmc.devices.jobs.card_driver import InstantDriver

    if isinstance(card, GrblCard) and runner.job.operation == "program":
        from flowmc.devices.jobs.grbl_driver import GrblDriver

        return GrblDriver(runner, card)

    return InstantDriver(runner, card)

