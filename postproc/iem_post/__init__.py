"""Post-processing of iem (Infinitesimal Element Model) HDF5 output: reader, plots and CLI."""

from __future__ import annotations

__version__ = "0.1.0"

from .reader import (  # noqa: E402
    Frame,
    FrameIndexError,
    FrameInfo,
    IemFile,
    IemFileError,
    IncompleteFileWarning,
    Mesh,
    Probe,
)

__all__ = [
    "__version__",
    "IemFile",
    "IemFileError",
    "FrameIndexError",
    "IncompleteFileWarning",
    "Mesh",
    "FrameInfo",
    "Frame",
    "Probe",
]
