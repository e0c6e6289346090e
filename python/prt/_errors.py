"""The exceptions and warnings the prt package raises.

Every error the libraries report is raised as a ``PrtError`` carrying the library's message
(the same text the command-line tools print); the subclasses say what kind of input was at
fault, and each also derives from the built-in exception a caller may already catch.
"""

__all__ = ["PrtError", "FileError", "ConfigError", "ParameterError", "Cancelled", "PrtWarning"]


class PrtError(Exception):
    """An error reported by PRT bake's libraries (the message says what and where)."""


class FileError(PrtError, OSError):
    """A file is missing, unreadable, corrupt, or not what was expected (a bake file of the
    other kind, an image that is no environment map)."""


class ConfigError(PrtError, ValueError):
    """A bake config or its scene was refused (an unknown key, a value out of range, a scene
    with nothing to bake, a setting of the other kind of bake)."""


class ParameterError(PrtError, ValueError):
    """A value given to the API was refused: an unknown material or parameter, a value
    outside its range, a camera or environment that cannot be used, an array of the wrong
    shape or dtype."""


class Cancelled(PrtError):
    """A bake or reference render was stopped because its progress callback returned False."""


class PrtWarning(UserWarning):
    """Something that may be wrong but did not stop the work (issued when no progress
    callback takes warnings)."""


for _cls in (PrtError, FileError, ConfigError, ParameterError, Cancelled, PrtWarning):
    _cls.__module__ = "prt"
del _cls
