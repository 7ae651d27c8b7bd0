"""The answer to a request (a capture, a service call): whether it was done, and the line that says
what happened or why not. A named pair, so that code reads ``answer.ok`` / ``answer.message``;
it unpacks as ``ok, message`` where a service fills its response."""

from __future__ import annotations

from typing import NamedTuple


class Answer(NamedTuple):
    ok: bool
    message: str
