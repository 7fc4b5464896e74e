"""Errors a user can cause. The CLI prints their message, without a traceback, and exits 2."""

from __future__ import annotations

import difflib


class SenbenchError(Exception):
    """Base class: the message says what to change."""

    exit_code = 2


class PluginError(SenbenchError):
    """A plugin failed to load or registered something invalid."""


class SuiteError(SenbenchError):
    """A suite file is malformed or names something that does not exist."""


class ResultsError(SenbenchError):
    """A results folder is missing or holds no readable results."""


class OutputError(SenbenchError):
    """A file a command was asked to write cannot be written there."""


class EncoderCacheError(SenbenchError):
    """A cached state encoder's files are damaged (truncated, altered, unloadable)."""


class NonFiniteError(SenbenchError):
    """A cell's observations, actions, rewards or returns became NaN or infinite."""


class UnknownNameError(SenbenchError):
    def __init__(self, kind: str, name: str, known: list[str], note: str = ""):
        """``note``: appended, e.g. that a disabled plugin provides ``name``."""
        self.kind, self.name, self.known = kind, name, sorted(known)
        super().__init__(unknown_name_message(kind, name, self.known) + note)


def unknown_name_message(kind: str, name: str, known: list[str]) -> str:
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
    hint = f" Did you mean '{close[0]}'?" if close else ""
    listing = ", ".join(sorted(known)) if known else "none installed"
    return f"unknown {kind} '{name}'.{hint} Known {kind}s: {listing}."
