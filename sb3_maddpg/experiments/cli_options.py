"""The command line's options, derived from the config model: one option per field of a dataclass (or parameter of a
function), named after it (``n_checkpoints`` is ``--n-checkpoints``), typed by its annotation and explained by its
``:param:`` docstring. jsonargparse parses each value by its type (an integer, ``null``, a JSON or YAML list or
mapping), so a field added to a config is an option without a line here."""

import argparse
import dataclasses
import inspect
import re
import typing
from collections.abc import Callable, Iterable, Iterator
from typing import Any, NamedTuple

import docstring_parser
from jsonargparse import ActionYesNo

GIVEN_ONLY = argparse.SUPPRESS
"""An option's default that leaves it out of the parsed arguments unless given (an override of a loaded config)."""


class Option(NamedTuple):
    """One field or parameter as an option: its name, type, default and help."""

    name: str
    hint: Any
    default: Any
    help: str


def options_of(source: type | Callable[..., Any], skip: Iterable[str] = ()) -> Iterator[Option]:
    """
    :param source: A dataclass (its fields) or a function (its parameters with a default).
    :param skip: Names to leave out.
    :return: Each field or parameter with its type, default (``dataclasses.MISSING`` for none) and ``:param:`` text
        (a dataclass's from its class and the classes it derives from).
    """
    hints = typing.get_type_hints(source)
    docs: dict[str, str] = {}
    for owner in reversed(getattr(source, "__mro__", (source,))):
        docs |= {param.arg_name: param.description or "" for param in docstring_parser.parse(owner.__doc__ or "").params}
    if dataclasses.is_dataclass(source):
        entries = [(field.name, _default(field)) for field in dataclasses.fields(source)]
    else:
        entries = [
            (name, param.default)
            for name, param in inspect.signature(source).parameters.items()
            if param.default is not inspect.Parameter.empty
        ]
    for name, default in entries:
        if name not in skip:
            yield Option(name, hints[name], default, _plain(docs.get(name, "")))


def _default(field: dataclasses.Field) -> Any:
    """:return: A field's default (made by its factory), or ``dataclasses.MISSING``."""
    return field.default_factory() if field.default_factory is not dataclasses.MISSING else field.default


def _plain(text: str) -> str:
    """:return: A docstring's text for ``--help``: reST roles and literals as plain words, on one line."""
    text = re.sub(r":\w+:`~?([^`<]*?)(?: <[^>]*>)?`", lambda match: match.group(1).rsplit(".", 1)[-1], text)
    return " ".join(text.replace("``", "").split()).replace("%", "%%")


def add_options(group: Any, options: Iterable[Option], given_only: bool = False) -> list[str]:
    """
    Add one option per field: ``--<name with dashes>``; a boolean as ``--<name>`` / ``--no-<name>``.

    :param group: A jsonargparse parser or argument group.
    :param options: The fields (:func:`options_of`).
    :param given_only: Leave each out of the parsed arguments unless given (overrides), instead of its default.
    :return: The options' names (their destinations in the parsed arguments).
    """
    names = []
    for option in options:
        flag = "--" + option.name.replace("_", "-")
        default = GIVEN_ONLY if given_only or option.default is dataclasses.MISSING else option.default
        if option.hint is bool or set(typing.get_args(option.hint)) == {bool, type(None)}:
            group.add_argument(flag, action=ActionYesNo(no_prefix="no-"), default=default, help=option.help)
        else:
            group.add_argument(flag, type=option.hint, default=default, help=option.help)
        names.append(option.name)
    return names


def flag(name: str) -> str:
    """:return: The option of a field, e.g. ``--n-checkpoints`` for ``n_checkpoints``."""
    return "--" + name.replace("_", "-")
