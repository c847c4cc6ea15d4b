"""Exceptions shared by every layer (no dependencies)."""

from __future__ import annotations

from collections.abc import Iterable


class ConfigError(ValueError):
    """A user-facing configuration error naming the offending key.

    Parameters
    ----------
    key : str
        Dotted config key, e.g. ``"problem"`` or ``"optimizer.n_particles"``.
    message : str
        What is wrong with the value.
    allowed : iterable of str, optional
        The allowed values, listed in the message when given.
    """

    def __init__(self, key: str, message: str, allowed: Iterable[str] | None = None) -> None:
        self.key = key
        self.allowed = tuple(allowed) if allowed is not None else None
        text = f"{key}: {message}"
        if self.allowed:
            text += f" (allowed: {', '.join(self.allowed)})"
        super().__init__(text)
