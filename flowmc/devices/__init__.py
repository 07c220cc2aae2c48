"""Motion-card devices: one interface, the simulated card by default, GRBL and LinuxCNC behind it."""
