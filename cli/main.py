"""``geoproc``: the Typer application; each subcommand lives in its own module."""

from __future__ import annotations

import sys
import typing
from typing import Annotated

import typer

import geoproc
from geoproc_cli import denoise, geodesic, info, morse_simplify, perturb, wos_solve
from geoproc_cli.common import EXIT_BAD_INPUT, TYPED_OPTIONS, flag, say
from geoproc_cli.entry import interruption_line, unreported_interruption

app = typer.Typer(
    name="geoproc",
    help="Geometry-processing research methods as pipeline-friendly tools. "
    "Exit codes: 0 success, 1 a --check failed, 2 bad input or usage, 3 internal error, "
    "130 interrupted (Ctrl-C), 143 terminated (SIGTERM), 129 hung up (SIGHUP).",
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
        bool, flag("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    """Geometry-processing research methods as pipeline-friendly tools."""


def _refusing_repeats(make_parser):
    """Wrap a command's ``make_parser`` so that an option taking one value,
    given more than once, is a usage error: the parser keeps the last one, so
    ``-o a.ply -o b.ply`` wrote only b.ply and ``--seed 1 --seed 2`` ran seed 2,
    without a word. Repeatable options (``-s``, ``--check``) and flags are not
    affected. A numeric option's value spelled with Python's digit separators
    (``--noise 1_0``, which ``float`` reads as 10 and ``--check`` refuses) is
    a usage error too."""
    def make(ctx):
        parser = make_parser(ctx)
        parse = parser.parse_args

        def parse_args(args):
            given = list(args)  # (the parser consumes the list)
            opts, rest, order = parse(args=args)
            _keep_typed(order, opts, given)
            seen = set()
            for param in order:
                single = (getattr(param, "param_type_name", "") == "option"
                          and not (param.multiple or param.count or param.is_flag))
                if single and param.name in seen:
                    ctx.fail(f"{' / '.join(param.opts)} given more than once; it takes one value")
                seen.add(param.name)
                spelled = _separated_number(param, opts.get(param.name))
                if spelled is not None:
                    ctx.fail(f"{max(param.opts, key=len)} '{spelled}': write the number without '_'")
            return opts, rest, order

        parser.parse_args = parse_args
        return parser

    return make


def _keep_typed(order, opts: dict, args: list[str]) -> None:
    """Keep each single-value option's form and raw text in
    :data:`cli.common.TYPED_OPTIONS` (the long form when it was typed before
    any ``--``, else the short one), for messages that name a value as typed."""
    before = args[:args.index("--")] if "--" in args else args
    TYPED_OPTIONS.clear()
    for param in order:
        raw = opts.get(param.name)
        if getattr(param, "param_type_name", "") != "option" or not isinstance(raw, str):
            continue
        long = max(param.opts, key=len)
        typed_long = any(a == long or a.startswith(long + "=") for a in before)
        short = [o for o in param.opts if not o.startswith("--")]
        TYPED_OPTIONS[param.name] = (long if typed_long or not short else short[0], raw)


def command():
    """The click group of :data:`app`, its subcommands refusing repeated
    single-value options (:func:`_refusing_repeats`)."""
    group = typer.main.get_command(app)
    for sub in group.commands.values():
        sub.make_parser = _refusing_repeats(sub.make_parser)
        sub.get_help_option = _without_value_column(sub.get_help_option)
    group.get_help_option = _without_value_column(group.get_help_option)
    return group


def _without_value_column(get_help_option):
    """``get_help_option`` whose option shows no value column in ``--help``
    (typer showed ``<bool>`` there, as if ``--help`` took a value; the
    project's own flags leave it empty, see :func:`cli.common.flag`)."""
    def get(ctx):
        option = get_help_option(ctx)
        if option is not None:
            option.metavar = ""
        return option

    return get


def _stop(exc: KeyboardInterrupt) -> None:
    """Exit with the error line and status of an interruption (Ctrl-C, termination)."""
    text, status = interruption_line(exc)
    say(f"error: {text}")
    sys.exit(status)


def _numeric(annotation) -> bool:
    """Whether a parameter annotated so takes numbers (``float``, ``int``,
    ``int | None``, ``list[int]``; not ``bool``)."""
    if annotation in (int, float):
        return True
    return any(_numeric(a) for a in typing.get_args(annotation) if a is not type(None))


def _separated_number(param, raw) -> str | None:
    """The first raw value of a numeric option ``param`` written with digit
    separators ('1_0'), else None."""
    descriptor = getattr(param, "type_descriptor", None)
    if getattr(param, "param_type_name", "") != "option" or not _numeric(getattr(descriptor, "annotation", None)):
        return None
    values = raw if isinstance(raw, list | tuple) else [raw]
    return next((v for v in values if isinstance(v, str) and "_" in v and _reads_as_number(v)), None)


def _reads_as_number(text: str) -> bool:
    """Whether ``text`` is a number as ``float`` reads it (``1_0`` is; a file
    name such as ``my_mesh.ply`` given where a number belongs is not: the
    parser's own 'invalid value' error suits it)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def main() -> None:
    """Console-script entry point.

    Usage errors the option parser finds (unknown option, value out of range,
    missing argument) are one line, ``error: <problem> (see '<command> --help')``,
    with exit code 2, like the errors of the subcommands themselves.
    """
    if len(sys.argv) == 1:  # bare `geoproc`: a usage error like any other
        say("error: missing command: info, geodesic, wos-solve, morse-simplify, denoise or perturb "
            "(see 'geoproc --help')")
        sys.exit(EXIT_BAD_INPUT)
    try:
        code = command()(standalone_mode=False)
    except KeyboardInterrupt as exc:  # while typer builds the commands from their signatures
        _stop(exc)
    except typer.Abort as exc:
        if isinstance(exc.__cause__, KeyboardInterrupt):  # Ctrl-C or termination while the options are parsed
            _stop(exc.__cause__)
        say("error: aborted")
        sys.exit(EXIT_BAD_INPUT)
    except Exception as exc:  # the parser's usage errors (click's ClickException family)
        if not callable(getattr(exc, "format_message", None)):
            raise
        ctx = getattr(exc, "ctx", None)
        # an option missing its value comes without a context: the command is argv's first word
        words = [w for w in sys.argv[1:2] if not w.startswith("-")]
        path = ctx.command_path if ctx is not None else " ".join(["geoproc", *words])
        hint = f" (see '{path} --help')"
        message = " ".join(exc.format_message().split())
        say(f"error: {message}{hint}")
        sys.exit(EXIT_BAD_INPUT)
    stop = unreported_interruption()
    if stop is not None:
        _stop(stop)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":  # python -m geoproc_cli.main: as the console script, once loaded
    from geoproc_cli.entry import install_signal_handlers

    install_signal_handlers()
    main()
