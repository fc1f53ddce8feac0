"""What every standard-format file says about where it came from: the collection's start time,
the moment the file was made, and sarmitsuba's metadata without the user's paths.

Shared by :mod:`~sarmitsuba.formats.cphd`, :mod:`~sarmitsuba.formats.sicd` and
:mod:`~sarmitsuba.formats.geotiff`, each of which turns a ValueError into its own error type
naming the file.
"""
from __future__ import annotations

import datetime
import re
from typing import Any

from ..core.radar import utc_time

__all__ = ["DEFAULT_COLLECTION_START", "collection_start", "utc_now", "portable_metadata"]

#: The collection start of data without one (earlier versions, synthetic data): a fixed time keeps
#: their files reproducible.
DEFAULT_COLLECTION_START = datetime.datetime(2000, 1, 1, tzinfo=datetime.timezone.utc)


def collection_start(metadata: Any) -> datetime.datetime:
    """The first pulse's UTC time (aware datetime) from ``metadata["radar"]["collection_start"]``
    (sensor parameter ``collection_start``, :func:`sarmitsuba.core.radar.utc_time`);
    :data:`DEFAULT_COLLECTION_START` when missing or None. Raises ValueError (a ParameterError)
    for a time without a UTC offset or that is not ISO 8601."""
    radar = metadata.get("radar") if isinstance(metadata, dict) else None
    text = radar.get("collection_start") if isinstance(radar, dict) else None
    if text is None:
        return DEFAULT_COLLECTION_START
    return datetime.datetime.fromisoformat(utc_time(text))


def utc_now() -> datetime.datetime:
    """The present moment, UTC: when a file is made."""
    return datetime.datetime.now(datetime.timezone.utc)


def portable_metadata(metadata: Any) -> Any:
    """A copy of ``metadata`` (JSON-like: dicts, lists, scalars) whose every ``"scene_path"`` string,
    at any depth, is cut to its file name (``/home/me/scenes/a.xml`` and ``C:\\s\\a.xml`` give
    ``a.xml``): no absolute path of the user's machine travels in a file."""
    if isinstance(metadata, dict):
        return {key: (re.split(r"[\\/]", value)[-1] if key == "scene_path" and isinstance(value, str)
                      else portable_metadata(value)) for key, value in metadata.items()}
    if isinstance(metadata, (list, tuple)):
        return [portable_metadata(value) for value in metadata]
    return metadata
