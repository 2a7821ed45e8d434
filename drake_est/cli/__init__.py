"""The ``drake-est`` command line.

Subcommands live in modules of this package; each module defines
``register(subparsers)`` which adds its parser and sets ``func`` to a
callable taking the parsed ``args`` and returning an exit code.  Modules are
discovered automatically, so adding a subcommand means adding one file.

Errors derived from :class:`drake_est.errors.DrakeEstError` (and missing files)
are printed as one line on stderr with exit code 2, never as a traceback.
"""
from __future__ import annotations

import os

# Small per-step linear algebra runs several times faster single-threaded on shared 2-core machines
# (shared/drake_notes.md); set before numpy is imported. A user's own setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import pkgutil  # noqa: E402
import sys  # noqa: E402

from drake_est.errors import DrakeEstError  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    parser = _ArgumentParserExit2(
        prog="drake-est",
        description="System identification and estimation for robots, as Drake systems "
        "(methods of Bagge Carlson 2018).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_ArgumentParserExit2)
    pkg = sys.modules[__name__]
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(mod, "register"):
            mod.register(sub)
    return parser


class _ArgumentParserExit2(argparse.ArgumentParser):
    """Usage errors as one line on stderr (exit code 2), as promised for all bad input."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    import warnings

    def _one_line_warning(message, category, filename, lineno, file=None, line=None):
        # a Python warning is one stderr line like the project's own warnings (not file:line + source)
        print(f"drake-est {args.command}: warning: {category.__name__}: {str(message).splitlines()[0][:300]}",
              file=sys.stderr)

    old_show = warnings.showwarning
    warnings.showwarning = _one_line_warning
    try:
        return _dispatch(parser, args)
    finally:
        warnings.showwarning = old_show


def _dispatch(parser, args) -> int:
    try:
        rc = args.func(args)
    except DrakeEstError as err:
        print(f"drake-est {args.command}: error: {err}", file=sys.stderr)
        return 2
    except FileNotFoundError as err:
        print(f"drake-est {args.command}: error: file not found: {err.filename or err}", file=sys.stderr)
        return 2
    except FileExistsError as err:
        print(f"drake-est {args.command}: error: {err.filename or err} exists and is not a folder "
              "(an output folder is needed here)", file=sys.stderr)
        return 2
    except NotADirectoryError as err:
        print(f"drake-est {args.command}: error: {err.filename or err}: a part of this path is a file, "
              "not a folder", file=sys.stderr)
        return 2
    except IsADirectoryError as err:
        print(f"drake-est {args.command}: error: {err.filename or err} is a folder, expected a file", file=sys.stderr)
        return 2
    except PermissionError as err:
        print(f"drake-est {args.command}: error: permission denied: {err.filename or err}", file=sys.stderr)
        return 2
    except OSError as err:  # read-only file system, disk full, device errors: name the path
        where = err.filename or "output file"
        print(f"drake-est {args.command}: error: cannot read or write {where}: {err.strerror or err}",
              file=sys.stderr)
        return 2
    except UnicodeDecodeError:
        name = (getattr(args, "log", None) or getattr(args, "data", None) or getattr(args, "source", None)
                or "input file")
        if isinstance(name, list):
            name = " / ".join(str(n) for n in name)
        print(f"drake-est {args.command}: error: {name} is not a text CSV (binary or wrong encoding; "
              "expected a UTF-8 CSV with a header, or an NPZ)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"drake-est {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(rc or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
