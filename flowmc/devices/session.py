"""The one device connection an application holds: the editor's Device tab and its job runner share it,
so a serial port or a LinuxCNC session is never opened twice by the same editor.

``connect`` opens a card through ``open_device`` (closing the one before); ``card`` is the open card
(None when disconnected). Every call on it goes through ``lock`` when several threads use it.
"""

from __future__ import annotations

import threading
from typing import Any

from flowmc.devices.backends import known_devices, open_device
from flowmc.devices.card import MotionCard
from flowmc.motion.machine import Machine

__all__ = ["DeviceSession"]


class DeviceSession:
    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.card: MotionCard | None = None
        self.spec = ""

    def known(self) -> list[str]:
        """Device specs that can be opened (``sim``, ``grbl:<serial port>``, ...)."""
        return known_devices()

    def connect(self, spec: str, machine: Machine | None = None, **options: Any) -> MotionCard:
        """Open ``spec`` (DeviceError says why not); the card open before is closed first."""
        with self.lock:
            self.disconnect()
            self.card = open_device(spec, machine, **options)
            self.spec = spec.strip()
            return self.card

    def disconnect(self) -> None:
        """Close the open card (errors closing it are raised after it is forgotten)."""
        with self.lock:
            card, self.card, self.spec = self.card, None, ""
            if card is not None:
                card.close()

    def input_names(self) -> dict[int, str]:
        """What the open card's digital inputs are wired to, by channel."""
        with self.lock:
            return self.card.input_names() if self.card is not None else {}

    def close(self) -> None:
        self.disconnect()
