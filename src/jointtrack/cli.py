"""The ``jointtrack`` command line."""

from __future__ import annotations

import importlib

import typer

from jointtrack import __version__

app = typer.Typer(
    name="jointtrack",
    help="Exact, fast and honest multi-target association.",
    no_args_is_help=True,
    add_completion=False,
)
bench_app = typer.Typer(help="Benchmarks against the peer libraries, timed in the same run.")
app.add_typer(bench_app, name="bench")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"jointtrack {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """jointtrack: JPDA, permanents, identity and superpositional-sensor filters."""


def _run_bench(name: str, quick: bool, out) -> None:
    module = importlib.import_module(f"jointtrack.bench.{name}")
    module.run(quick=quick, out=out)


@bench_app.command("permanent")
def bench_permanent(
    quick: bool = typer.Option(False, "--quick", help="Smaller sizes; finishes in seconds."),
    out: str = typer.Option(None, "--out", help="Also write the results as JSON to this file."),
) -> None:
    """Permanent engine vs thewalrus on DESIGN.md's canonical workloads."""
    _run_bench("permanent", quick, out)


@bench_app.command("association")
def bench_association(
    quick: bool = typer.Option(False, "--quick", help="Smaller sizes; finishes in seconds."),
    out: str = typer.Option(None, "--out", help="Also write the results as JSON to this file."),
) -> None:
    """JPDA association engine vs Stone Soup and pyehm on the canonical clusters."""
    _run_bench("association", quick, out)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
