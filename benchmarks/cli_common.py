"""What the command modules share: exit codes and the harness-failure exit (so that
:mod:`.cli` and the command modules it registers import it from here, not from each other)."""

from __future__ import annotations

import sys

import click

EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def exit_on_harness_errors(errors: list[str], shown: int = 3, width: int = 160) -> None:
    """Exit 1 naming the first failures of the simulation or the scorer (none: return)."""
    if not errors:
        return
    first = "; ".join(e if len(e) <= width else e[: width - 3] + "..." for e in errors[:shown])
    more = f" (and {len(errors) - shown} more)" if len(errors) > shown else ""
    click.echo(f"exobench: {len(errors)} records failed in the simulation or the scorer, not in a pipeline: {first}{more}", err=True)
    sys.exit(EXIT_FAILED)
