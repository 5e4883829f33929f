"""Helpers shared by the CLI tests (put on sys.path by tests/cli/conftest.py)."""

from __future__ import annotations

import inspect

from click.testing import CliRunner
from rangekit_cli.main import cli


def run(args, **kw):
    """Invoke ``rangekit ARGS`` in-process; arguments are str()-ed."""
    return CliRunner().invoke(cli, [str(a) for a in args], prog_name="rangekit", **kw)


def ok(result):
    """Assert exit 0 (showing stderr otherwise) and return the result."""
    assert result.exit_code == 0, (result.exit_code, result.stderr, result.exception)
    return result


def assert_error(result, code: int, *names: str) -> str:
    """Exit ``code``; stderr is one line ``rangekit: error: ...`` naming every ``names``."""
    assert result.exit_code == code, (result.exit_code, result.stderr, result.exception)
    err = result.stderr
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert err.endswith("\n")
    assert lines[0].startswith("rangekit: error: "), err
    for n in names:
        assert n in lines[0], (n, err)
    return lines[0]


def with_defaults(fn, **new):
    """``fn`` with other keyword defaults in its signature (what the CLI reads when it
    shows or uses a library default), for monkeypatching the library."""

    def wrapped(*args, **kw):
        return fn(*args, **kw)

    sig = inspect.signature(fn)
    params = [p.replace(default=new.get(n, p.default)) for n, p in sig.parameters.items()]
    wrapped.__signature__ = sig.replace(parameters=params)
    return wrapped
