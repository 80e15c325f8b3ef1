"""tests/support/checks.py: a failed worker check names itself and the values behind it."""
from __future__ import annotations

import pytest

from tests.support.checks import expect

REPORT = {
    "cycles_clean": False,
    "cycles_clean_values": {"handler": None, "live_resources": 3, "handlers_after": {"load_post": 2}},
    "error_logged_once": False,
    "error_logged_once_values": {"logged": ["synthetic failure", "synthetic failure"]},
    "recovered": True,
    "recovered_values": {"draw": True, "last_error": ""},
    "running_after": True,
    "pointer_removed": True,
}


def _message(*names: str, **context) -> str:
    with pytest.raises(AssertionError) as caught:
        expect(REPORT, *names, **context)
    return str(caught.value)


def test_passing_checks_pass() -> None:
    expect(REPORT, "recovered", "pointer_removed")
    expect({"running_after": False, "rows": 0}, "not running_after", "not rows")


def test_failure_names_each_failed_check_with_its_values() -> None:
    message = _message("cycles_clean", "recovered", "error_logged_once", "pointer_removed")
    assert message.startswith("2 of 4 worker checks failed:"), message
    assert "cycles_clean = False (expected truthy)" in message
    assert "cycles_clean_values = {'handler': None, 'live_resources': 3, 'handlers_after': {'load_post': 2}}" \
        in message
    assert "error_logged_once = False" in message
    assert "'logged': ['synthetic failure', 'synthetic failure']" in message
    # Passing checks, and the values behind them, stay out of the message.
    assert "recovered" not in message and "pointer_removed" not in message


def test_negated_check_fails_on_a_truthy_entry() -> None:
    message = _message("not running_after", "recovered")
    assert message.startswith("1 of 2 worker checks failed:"), message
    assert "running_after = True (expected falsy)" in message


def test_missing_check_fails_and_lists_the_keys() -> None:
    message = _message("handlers_restored")
    assert "handlers_restored is missing from the report" in message
    assert "'pointer_removed'" in message  # the keys the report does have


def test_context_ends_the_message() -> None:
    message = _message("cycles_clean", stage="after install", camera="shifted")
    assert message.endswith("context:\n  stage = 'after install'\n  camera = 'shifted'"), message


def test_long_values_stay_readable() -> None:
    """Values wider than a line are pretty-printed, indented under their check."""
    report = {"state_freed": False, "state_freed_values": {f"key_{i}": list(range(10)) for i in range(6)}}
    with pytest.raises(AssertionError) as caught:
        expect(report, "state_freed")
    lines = str(caught.value).splitlines()
    assert lines[2].startswith("    state_freed_values = {'key_0'")
    # Continuation lines start under the value's opening brace.
    column = lines[2].index("{") + 1
    assert len(lines) > 3 and all(line.startswith(" " * column + "'key_") for line in lines[3:]), lines


def test_no_names_is_a_mistake() -> None:
    with pytest.raises(TypeError):
        expect(REPORT)
