"""Assertions on the reports that child-process test workers send back.

A worker (tests/support/*_worker.py) reports each check as one entry of a dict, true
when the check passed. Where a flag is computed from numbers (counts, lists, shares),
the worker also stores what it was computed from as `<name>_values`, so that a
failure can say why: `expect` names every failed check, its value, and that entry.
"""
from __future__ import annotations

import pprint
from collections.abc import Mapping
from typing import Any

VALUES_SUFFIX = "_values"  # report[name + VALUES_SUFFIX]: the values behind report[name]
NEGATION = "not "  # expect(report, "not running_after"): the entry must be falsy


def _line(prefix: str, value: Any, suffix: str = "") -> str:
    """`prefix` then `value` as pprint writes it, its continuation lines aligned under its start."""
    shown = pprint.pformat(value, width=max(40, 110 - len(prefix)), sort_dicts=False)
    return prefix + shown.replace("\n", "\n" + " " * len(prefix)) + suffix


def failed_checks(report: Mapping[str, Any], *names: str) -> list[str]:
    """One block of message text per named check that fails: its value, then the values behind it."""
    blocks = []
    for name in names:
        negated = name.startswith(NEGATION)
        key = name.removeprefix(NEGATION)
        if key not in report:
            blocks.append(f"  {key} is missing from the report (its keys: {sorted(report)})")
            continue
        if bool(report[key]) != negated:
            continue
        block = _line(f"  {key} = ", report[key], f" (expected {'falsy' if negated else 'truthy'})")
        if key + VALUES_SUFFIX in report:
            block += "\n" + _line(f"    {key}{VALUES_SUFFIX} = ", report[key + VALUES_SUFFIX])
        blocks.append(block)
    return blocks


def expect(report: Mapping[str, Any], *names: str, **context: Any) -> None:
    """Assert the named checks of a worker's report, all of them before failing.

    `name` asserts that report[name] is truthy, "not name" that it is falsy; a name
    missing from the report fails. The AssertionError lists each failed check as
    `name = value`, followed by report[name + "_values"] where the worker stored the
    values behind the flag, and ends with `context` (which case, which stage...).
    """
    __tracebackhide__ = True  # pytest then points at the test's line, not at this helper
    if not names:
        raise TypeError("expect() needs at least one check name")
    blocks = failed_checks(report, *names)
    if blocks:
        message = [f"{len(blocks)} of {len(names)} worker checks failed:", *blocks]
        if context:
            message += ["context:", *(_line(f"  {key} = ", value) for key, value in context.items())]
        raise AssertionError("\n".join(message))
