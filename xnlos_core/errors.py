"""Exceptions raised by xnlos; each message names the input, its value and what is allowed."""


class XnlosError(Exception):
    """Base class of every error xnlos raises on purpose."""


class InputError(XnlosError, ValueError):
    """An array or value handed to xnlos is malformed (shape, dtype, NaN, range)."""


class ConfigError(XnlosError, ValueError):
    """A configuration file or table is invalid; the message names file, key and allowed values."""


class PluginError(XnlosError, LookupError):
    """A plugin is unknown, registered twice or does not honour its interface."""


class InsufficientDataError(XnlosError, ValueError):
    """A stage was given too little data to produce a result (e.g. a wall from < 2 LOS points)."""


class SchemaKeywordError(InputError):
    """A JSON Schema uses a keyword that :mod:`xnlos_core.app.json_schema` does not implement."""


class SchemaViolation(InputError):
    """A record does not match its schema; ``path`` is the key path of the offending value
    (e.g. ``walls[0].cov``), ``reason`` what was expected there."""

    def __init__(self, path: str, reason: str):
        super().__init__(f"{path or '<record>'}: {reason}")
        self.path, self.reason = path, reason


class XnlosWarning(UserWarning):
    """Base class of every warning xnlos issues on purpose (the CLI prints them as ``xnlos: warning: …``)."""


class GridMismatchWarning(XnlosWarning):
    """A model is used on maps of another radar or RA grid than it was trained on (carrier, range or
    azimuth bins, spacing, field of view): its outputs are not what its validation figures describe."""


class PipelineWarning(XnlosWarning):
    """A pipeline is valid and runs, but cannot deliver part of what it is configured for (e.g. a
    detector that labels nothing mNLOS feeding a wall estimator and reconstructor: it never reconstructs)."""


class CheckpointWarning(XnlosWarning):
    """A resumable run's checkpoint (``stage_state.json``) cannot be used — not JSON, another
    configuration's, refused by a stage — so the run falls back to the slower way that needs none
    (replaying its frames from 0); the results are the same."""


class LegacyRecordWarning(XnlosWarning):
    """A results.jsonl holds records of schema 1 (no ``schema_version``), which lack what schema 2
    added: per-detection rows, hidden-point covariances, wall extents and arc anchors."""


class MaterialFallbackWarning(XnlosWarning):
    """A wall material is used at a frequency outside its ITU-R P.2040 validity range, through the
    documented fallback of :mod:`sims.material_fallback` (e.g. brick at 77 GHz): the wall's ε and σ
    are not P.2040-covered values there. Issued once per material and frequency."""
