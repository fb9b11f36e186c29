# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""Usage errors, printed as one line ``orbitflex: error: FLAG: message`` (exit code 2), and the
argument types that raise them."""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import Any, NoReturn, Tuple


class CliError(Exception):
    """A usage error, printed as one line ``orbitflex: error: FLAG: message`` (exit code 2)."""

    def __init__(self, flag: str, message: str):
        super().__init__(f"{flag}: {message}")


def cli_words(message: str) -> str:
    """The library's message with its Python keywords (``ee_link``, ``locked_joints=[...]``)
    replaced by the command-line flags."""

    def locked(match: "re.Match[str]") -> str:
        names = [name.strip().strip("'\"") for name in match.group(1).split(",")]
        return "--locked-joints " + ",".join(names)

    # a list of what the file has names links and joints, not keywords: left as it is
    head, sep, listing = message.partition("; the file has: ")
    head = re.sub(r"locked_joints=\[([^\]]*)\]", locked, head)
    # the keywords, not a link or joint of that name (names are quoted: 'ee_link')
    head = re.sub(r"(?<![\w'\"-])locked_joints(?![\w'\"])", "--locked-joints", head)
    head = re.sub(r"(?<![\w'\"-])ee_links(?![\w'\"])", "--ee-links", head)
    return re.sub(r"(?<![\w'\"-])ee_link(?![\w'\"])", "--ee-link", head) + sep + listing


def urdf_error(error: Exception) -> CliError:
    """A URDF-loading error, under the flag it blames: ``--ee-link`` or ``--locked-joints`` if
    its statement (before the first ``; ``, where advice begins) names one (the first one it
    names), else ``URDF``. Advice such as "lock them with --locked-joints a,b" blames no flag."""
    message = cli_words(str(error))
    statement = message.split("; ", 1)[0]
    named = [(found.start(), flag) for flag in ("--ee-link", "--ee-links", "--locked-joints")
             for found in [re.search(re.escape(flag) + r"(?![\w-])", statement)] if found]
    if not named:
        return CliError("URDF", message)
    flag = min(named)[1]
    # "unknown link (--ee-link) 'x'" reads "unknown link 'x'" once the flag leads the line
    message = message[len(flag) + 2:] if message.startswith(flag + ": ") else message
    return CliError(flag, re.sub(rf" \((?:in )?{flag}\)", "", message))


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``orbitflex: error: --dt: ...`` (exit code 2), and no
    abbreviated flags (``--dur`` is an error, not ``--duration``: a flag added later must not
    change what an existing script means)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        message = re.sub(r"^argument ([^:/ ]+)(?:/\S+)?: ", r"\1: ", message)
        fail(f"{message} (see '{self.prog} --help')")


def fail(message: str) -> NoReturn:
    print(f"orbitflex: error: {message}", file=sys.stderr)
    sys.exit(2)


def positive(text: str) -> float:
    value = finite(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, given {text}")
    return value


def finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, given {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, given {text}")
    return value


def package_dir(text: str) -> Tuple[str, str]:
    """``--package NAME=DIR``."""
    name, sep, folder = text.partition("=")
    if not sep or not name or not folder:
        raise argparse.ArgumentTypeError(f"expected NAME=DIR (a ROS package and its folder), given {text}")
    if not Path(folder).is_dir():
        raise argparse.ArgumentTypeError(f"package '{name}': {folder} is not a folder")
    return name, folder


def output_folder(path: str) -> Path:
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise CliError("--out", f"{out} exists and is not a folder; name a folder (created if missing)")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise CliError("--out", f"cannot create the folder {out}: {e.strerror or e}") from None
    return out


def at_least_one(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, given {text}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, given {text}")
    return value


def non_negative(text: str) -> float:
    value = finite(text)
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, given {text}")
    return value
