"""Reading and writing the files graphs name, the one way: bounded, never hanging, never half-written.

- ``read_bytes`` / ``read_text`` refuse anything that is not a regular file *before* reading (a FIFO
  named ``part.ngc`` would block the reader for ever; a device would never end), refuse files over a
  size limit (the caller's budget) without reading them, and decode UTF-8 with or without a BOM.
- ``write_atomic`` writes a temp file beside the target, fsyncs, and renames it over the target:
  readers see the old file or the new one, never half of one. The temp file is anonymous while it is
  written (Linux ``O_TMPFILE``), so a kill -9 mid-write leaves nothing; it gets a short name of its
  own (``.flowmc-<pid>-<random>.tmp``, whatever the target's length) only for the instant before the
  rename, and a later write into the folder removes any such file whose process is gone.

Errors are ``error`` (a FlowmcError subclass the caller picks) naming the file.
"""

from __future__ import annotations

import hashlib
import os
import re
import secrets
import stat
from pathlib import Path
from typing import Type

from flowmc.errors import FlowmcError

__all__ = ["read_bytes", "read_text", "write_atomic", "fingerprint", "TEMP_PATTERN"]

TEMP_PATTERN = re.compile(r"^\.flowmc-(\d+)-[0-9a-f]{16}\.tmp$")
_CHUNK = 1 << 20


def read_bytes(path: str | os.PathLike, *, limit: int | None = None, what: str = "file",
               error: Type[FlowmcError] = FlowmcError) -> bytes:
    """The bytes of a regular file; ``error`` if it is missing, not a regular file, or over ``limit`` bytes."""
    name = os.fspath(path)
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise error(f"no such {what}", where=name) from None
    except (OSError, ValueError) as exc:
        raise error(f"cannot read the {what}: {getattr(exc, 'strerror', None) or exc}", where=name) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a pipe or device"
            raise error(f"the {what} is {kind}, not a regular file", where=name)
        if limit is not None and info.st_size > limit:
            raise error(f"the {what} is {info.st_size:,} bytes, over the budget of {limit:,} "
                        f"(raise it with flowmc run --memory-mb or FLOWMC_MEMORY_MB)", where=name)
        chunks, total = [], 0
        while True:  # read to the end, but never past the limit (a file may grow while it is read)
            chunk = os.read(fd, _CHUNK)
            if not chunk:
                break
            total += len(chunk)
            if limit is not None and total > limit:
                raise error(f"the {what} grew past the budget of {limit:,} bytes while it was read", where=name)
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise error(f"cannot read the {what}: {exc.strerror or exc}", where=name) from None
    finally:
        os.close(fd)


def read_text(path: str | os.PathLike, *, limit: int | None = None, what: str = "file",
              error: Type[FlowmcError] = FlowmcError) -> str:
    """``read_bytes`` decoded as UTF-8; a leading byte-order mark is dropped."""
    data = read_bytes(path, limit=limit, what=what, error=error)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"the {what} is not UTF-8 text (byte {exc.start})", where=os.fspath(path)) from None


def fingerprint(path: str | os.PathLike, limit: int | None = None) -> str | None:
    """A hash of the file's content, read in chunks (None if it is not a readable regular file, or is
    over ``limit`` bytes): whether a file changed, even when its size and modification time did not."""
    try:
        fd = os.open(os.fspath(path), os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except (OSError, ValueError):
        return None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or (limit is not None and info.st_size > limit):
            return None
        h = hashlib.blake2b(digest_size=16)
        while chunk := os.read(fd, _CHUNK):
            h.update(chunk)
        return h.hexdigest()
    except OSError:
        return None
    finally:
        os.close(fd)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # someone else's process
    return True


def _sweep(folder: Path) -> None:
    """Remove temp files a killed writer left in ``folder``."""
    try:
        names = [e.name for e in os.scandir(folder) if e.name.startswith(".flowmc-")]
    except OSError:
        return
    for name in names:
        match = TEMP_PATTERN.match(name)
        if match and int(match.group(1)) != os.getpid() and not _alive(int(match.group(1))):
            try:
                os.unlink(folder / name)
            except OSError:
                pass


def _temp_name(folder: Path) -> str:
    return str(folder / f".flowmc-{os.getpid()}-{secrets.token_hex(8)}.tmp")


def _write_all(fd: int, mode: int, payload: bytes) -> None:
    os.fchmod(fd, mode)
    view = memoryview(payload)
    while view:
        view = view[os.write(fd, view):]
    os.fsync(fd)


def _write_temp(folder: Path, mode: int, payload: bytes) -> str:
    """The payload in a new file in ``folder``, durably; returns its (temp) name. Written anonymously
    where the OS can (nothing is left if the process dies), named only once complete."""
    if hasattr(os, "O_TMPFILE"):
        try:
            fd = os.open(folder, os.O_TMPFILE | os.O_WRONLY | os.O_CLOEXEC, mode)
        except OSError:
            fd = -1  # this file system has no anonymous files: use a named temp file
        if fd >= 0:
            try:
                _write_all(fd, mode, payload)
                name = _temp_name(folder)
                os.link(f"/proc/self/fd/{fd}", name, follow_symlinks=True)
                return name
            except OSError:
                pass  # no /proc to name it by: write it again under a name
            finally:
                os.close(fd)
    name = _temp_name(folder)
    fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, mode)
    try:
        _write_all(fd, mode, payload)
    except BaseException:
        os.close(fd)
        os.unlink(name)
        raise
    os.close(fd)
    return name


def write_atomic(path: str | os.PathLike, data: bytes | str, *, what: str = "file",
                 error: Type[FlowmcError] = FlowmcError) -> Path:
    """Replace ``path`` with ``data`` (str is written as UTF-8) in one step. A folder, or a symlink at
    ``path``, is refused: the rename would replace the link, the caller meant the file."""
    path = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        info = None
    except (OSError, ValueError) as exc:
        raise error(f"cannot write the {what}: {getattr(exc, 'strerror', None) or exc}", where=str(path)) from None
    if info is not None and stat.S_ISDIR(info.st_mode):
        raise error(f"a folder has this name; choose another name for the {what}", where=str(path))
    if info is not None and stat.S_ISLNK(info.st_mode):
        raise error("this name is a symbolic link; flowmc does not write through links", where=str(path))
    if info is not None and not stat.S_ISREG(info.st_mode):
        raise error("this name is a pipe or device, not a file", where=str(path))
    mode = stat.S_IMODE(info.st_mode) if info is not None else 0o644
    folder = path.parent
    _sweep(folder)
    temp: str | None = None
    try:
        temp = _write_temp(folder, mode, payload)
        os.replace(temp, path)
        temp = None
        try:  # the rename itself reaches the disk with the folder
            dir_fd = os.open(folder, os.O_RDONLY)
            try:
                os.fsync(dir_fd)
            finally:
                os.close(dir_fd)
        except OSError:
            pass
    except OSError as exc:
        raise error(f"cannot write the {what}: {exc.strerror or exc}", where=str(path)) from None
    finally:
        if temp is not None:
            try:
                os.unlink(temp)
            except OSError:
                pass
    return path
