"""Jobs: a device node prepares a ``Job`` (pre-flighted, nothing moves); an explicit Start hands it to
a ``JobRunner``, which streams it to the device, takes hold/resume/stop/e-stop and overrides, and
reports position, progress and I/O as it goes."""

from flowmc.devices.jobs.job import ACTIVE, FINAL, STATES, Job, JobEvent, JobStatus, SafeOutputs, gcode_line
from flowmc.devices.jobs.runner import FEED_RANGE, PACES, RAPID_STEPS, SPINDLE_RANGE, JobRunner, claim

__all__ = ["Job", "JobRunner", "JobEvent", "JobStatus", "SafeOutputs", "STATES", "ACTIVE", "FINAL", "PACES",
           "FEED_RANGE", "RAPID_STEPS", "SPINDLE_RANGE", "claim", "gcode_line"]
