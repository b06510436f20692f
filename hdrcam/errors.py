"""Errors a user can act on. The command line prints their message on one line and exits non-zero."""


class HdrcamError(Exception):
    """Base class: the message says what is wrong and what to do about it."""


class InputError(HdrcamError):
    """An input file, argument or array is missing, damaged or out of range."""


class OutputExistsError(HdrcamError):
    """An output would overwrite an existing file or an input."""


class ProfileError(InputError):
    """A capture profile does not follow the schema."""


class SamplingError(HdrcamError):
    """An optical simulation setting would alias (undersample) the wave field."""
