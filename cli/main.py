"""``geoproc``: the Typer application; each subcommand lives in its own module."""

from __future__ import annotations

from typing import Annotated

import typer

import geoproc
from geoproc_cli import denoise, geodesic, info, morse_simplify, perturb, wos_solve

app = typer.Typer(
    name="geoproc",
    help="Geometry-processing research methods as pipeline-friendly tools. "
    "Exit codes: 0 success, 1 a --check failed, 2 bad input or usage, 3 internal error.",
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="markdown",
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)

info.register(app)
geodesic.register(app)
wos_solve.register(app)
morse_simplify.register(app)
denoise.register(app)
perturb.register(app)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"geoproc {geoproc.__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    """Geometry-processing research methods as pipeline-friendly tools."""


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":
    main()
