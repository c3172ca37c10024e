"""The command line's options, derived from the config model: one option per field of a dataclass (or parameter of a
function), named after it (``n_checkpoints`` is ``--n-checkpoints``), typed by its annotation and explained by its
``:param:`` docstring. jsonargparse parses each value by its type (an integer, ``null``, a JSON or YAML list or
mapping), so a field added to a config is an option without a line here. Then the fields given on a command line
applied over a loaded config (:func:`override`), as ``run`` and ``tune`` do."""

import argparse
import dataclasses
import inspect
import re
import typing
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, Literal, NamedTuple

import docstring_parser
from jsonargparse import ActionYesNo

from sb3_maddpg.experiments.backends import BACKENDS, Execution
from sb3_maddpg.experiments.defaults import DEFAULT_ENV
from sb3_maddpg.experiments.setting import (
    NOTE_KEEPING_FIELDS,
    SETTING_KEYS,
    ExperimentConfig,
    merge_model_kwargs,
    scaled_schedule,
)

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


LISTS = {"schemes", "score_agents", "seeds"}
"""Fields of lists that also take one comma-separated (``--schemes full,selected``, ``--seeds 0,5``)."""


EXPERIMENT_OWN = tuple(f.name for f in dataclasses.fields(ExperimentConfig) if f.name not in SETTING_KEYS)
"""An experiment's fields beyond its setting's concerns: its name, schemes, seeds, description and per-scheme kwargs."""


def setting_options(concern: type = ExperimentConfig) -> list[Option]:
    """
    :param concern: A concern of a setting (:data:`~sb3_maddpg.experiments.setting.CONCERNS`), or
        ``ExperimentConfig`` for every field of an experiment.
    :return: Its fields as options, lists also comma-separated.
    """
    options = []
    for option in options_of(concern):
        if option.name == "seeds":  # an integer before a string: "3" is three seeds
            option = option._replace(hint=option.hint | int, help=option.help + " An integer N: 0..N-1.")
        if option.name in LISTS:
            option = option._replace(hint=option.hint | str)
        if option.name == "num_agent_neighbors":  # "all" for every other agent, as null says
            option = option._replace(hint=option.hint | Literal["all"], help=option.help + " Give null or all for all.")
        options.append(option)
    return options


def execution_options() -> list[Option]:
    """:return: The execution's fields as options: a backend of :data:`BACKENDS`, workers by the backend if not given."""
    backends = "; ".join(f"{name}: {entry.help}" for name, entry in BACKENDS.items())
    changes: dict[str, dict[str, Any]] = {
        "backend": {"hint": Literal[tuple(BACKENDS)], "help": backends},
        "workers": {
            "hint": int | None,
            "default": None,
            "help": "Parallel processes (local; default 1), or the CPUs of a "
            "local Ray instance (ray, batched-ray; default 0: all).",
        },
    }
    return [option._replace(**changes.get(option.name, {})) for option in options_of(Execution, skip=("verbose",))]


def given_fields(args: argparse.Namespace, names: Sequence[str]) -> dict[str, Any]:
    """:return: The fields among ``names`` that ``args`` holds (given), lists of names split at commas."""
    given = {name: getattr(args, name) for name in names if hasattr(args, name)}
    for name in LISTS & given.keys():
        if isinstance(given[name], str):
            given[name] = tuple(item.strip() for item in given[name].split(",") if item.strip())
    if isinstance(given.get("seeds"), tuple):
        try:
            given["seeds"] = tuple(int(seed) for seed in given["seeds"])
        except ValueError:
            raise ValueError(f"--seeds {args.seeds!r}: give integers, e.g. 0,5 or [0, 5], or a number of seeds.") from None
    if given.get("num_agent_neighbors") == "all":
        given["num_agent_neighbors"] = None
    if isinstance(given.get("seeds"), int):
        if given["seeds"] < 1:
            raise ValueError(f"--seeds {given['seeds']}: give a number of seeds of at least 1, or a list of seeds, e.g. [0].")
        given["seeds"] = tuple(range(given["seeds"]))
    return given


def override(experiment: ExperimentConfig, given: dict[str, Any], config: str) -> ExperimentConfig:
    """
    :param experiment: A loaded ``--config``.
    :param given: The fields given on the command line (:func:`given_fields`).
    :param config: What ``--config`` said, for the description.
    :return: The experiment with the given fields: ``model_kwargs`` merged over its own (``scheme_model_kwargs`` per
        scheme); with ``--episodes``, each evaluation count not given follows the budget
        (:func:`~sb3_maddpg.experiments.setting.scaled_schedule`); a setting changed is described by its new values
        after ``"<config> with <options>"``. A ``ValueError`` for the team of a task other than simple_spread.
    """
    changes = dict(given)
    task = changes.get("env", experiment.env)
    team = [flag(name) for name in ("n_agents", "num_agent_neighbors") if name in changes]
    if task != DEFAULT_ENV and team:
        raise ValueError(
            f"{team[0]} sets simple_spread's team, but the task is {task}, whose team is its own: change it through "
            "--env-kwargs (e.g. simple_tag's '{\"num_adversaries\": 4}'), or leave out " + " and ".join(team) + "."
        )
    if "model_kwargs" in changes:
        changes["model_kwargs"] = merge_model_kwargs(experiment.model_kwargs, changes["model_kwargs"])
    if "scheme_model_kwargs" in changes:
        changes["scheme_model_kwargs"] = {
            scheme: merge_model_kwargs(experiment.scheme_model_kwargs.get(scheme, {}), kwargs)
            for scheme, kwargs in {**experiment.scheme_model_kwargs, **changes["scheme_model_kwargs"]}.items()
        }
    scaled = False
    if "episodes" in changes:
        for name, value in scaled_schedule(experiment, changes["episodes"]).items():
            if name not in changes:
                changes[name] = value
                scaled = scaled or value != getattr(experiment, name)
    nulls: dict[str, Any] = {name: None for name, value in changes.items() if value is None}  # e.g. every neighbour
    changed = dataclasses.replace(experiment.replace(**changes), **nulls)
    flags = [flag(name) for name in given if name not in NOTE_KEEPING_FIELDS]
    if not flags or "description" in given:
        return changed
    return changed.described(f"{config} with {' '.join(flags)}" + (" (evaluation scaled to the budget)" if scaled else ""))
