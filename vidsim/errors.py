"""Project-wide error types: every user-facing failure names the file, field or value."""

from __future__ import annotations


class VidsimError(ValueError):
    """Base class of errors caused by bad input (caught by the CLI and printed on one line)."""


class ConfigError(VidsimError):
    """A configuration value is unknown, of the wrong type or not physical."""


class FootageError(VidsimError):
    """A footage folder, video, frame, calibration or meta file is missing or malformed."""
