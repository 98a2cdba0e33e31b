"""Assertions shared by the CLI tests."""

from __future__ import annotations


def one_line_error(result, *needles) -> str:
    """The run failed with exit code 2 and exactly one ``error:`` line holding every needle."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    errors = [ln for ln in result.output.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1, result.output
    for n in needles:
        assert n in errors[0], errors[0]
    return errors[0]
