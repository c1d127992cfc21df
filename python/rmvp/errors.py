"""The exceptions rmvp raises, one class per kind; each carries the message and, where a file
is at fault, its path (``error.path``)."""

from __future__ import annotations

from typing import Optional

__all__ = ["RmvpError", "InputError", "MissingFileError", "OptionError"]


class RmvpError(Exception):
    """Anything rmvp refuses or fails at. ``path`` names the file or folder at fault, if any."""

    path: Optional[str] = None


class InputError(RmvpError, ValueError):
    """A file or array that is broken, hostile or not what it should be (a truncated image, a
    path that leaves its folder, a camera that is not a camera, an array of the wrong shape)."""


class MissingFileError(RmvpError, FileNotFoundError):
    """A file or folder that does not exist."""


class OptionError(RmvpError, ValueError):
    """An option no run can take (an unknown name, a value out of range, options that differ
    from those a run being resumed was started with)."""
