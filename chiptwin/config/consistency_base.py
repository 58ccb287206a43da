"""What every cross-field rule of :mod:`chiptwin.config.consistency` shares: the refusal that
names the file, the key, the value and what is allowed."""

from __future__ import annotations

from chiptwin.config.fields import ScenarioError
from chiptwin.config.schema import Scenario


def _fail(s: Scenario, key: str, value: object, allowed: str) -> None:
    raise ScenarioError(s.source, key, value, allowed)


def _short(text: str) -> str:
    return text if len(text) <= 40 else f"{text[:37]}…"
