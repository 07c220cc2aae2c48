"""LinuxCNC: its interpreter (rs274) as a reference, and a LinuxCNC machine as a device."""
