"""A small mutation sample: one-operator changes to a module, one at a time, each run against the module's tests.

    python benchmarks/mutation_sample.py [--modules losses selection ...] [--per-module 6] [--seed 59]
    python benchmarks/mutation_sample.py --only buffers.py:246 losses.py:166   # those of the sample, again
    python benchmarks/mutation_sample.py --listed        # issue 59's eleven survivors, each against its new test
    python benchmarks/mutation_sample.py --first-draw    # the survivors of a first draw (see FIRST_DRAW)

Each mutant changes one token of the module's code (never a docstring, a comment or an f-string's text):

- a comparison: ``<`` <-> ``<=``, ``>`` <-> ``>=``, ``==`` <-> ``!=``;
- arithmetic: ``+`` <-> ``-``, ``*`` <-> ``/``, ``//`` -> ``*``;
- a number: ``n`` -> ``n + 1``;
- ``True`` <-> ``False``, ``and`` <-> ``or``.

Candidates whose mutated module does not compile (``*args`` -> ``/args``) are dropped; ``--per-module`` of the rest
are drawn, each module's with a generator of its own seeded by ``--seed`` and the module's name (so that an edit of
one module changes no other module's draw). Each mutant is written into the source file, the module's test files run with
``-x -q -m "not slow"`` under ``--timeout`` seconds (a run that fails or hangs kills it), and the file is restored in a
``finally`` before the next mutant: only the mutated line is put back, so an edit someone else made to the file
meanwhile is kept. Tests that already fail before any mutation (the baseline) are deselected. The test processes
write no bytecode, and a restore never lands in the same second as its mutant, so no stale ``.pyc`` of a mutant can be
imported afterwards.

It prints one line per mutant and, at the end, a markdown table of them; whether a survivor is equivalent is for a
reader to decide (see ``benchmarks/results/mutation_sample.md``).
"""

import argparse
import ast
import contextlib
import io
import os
import random
import re
import signal
import subprocess
import sys
import time
import tokenize
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

ROOT = Path(__file__).resolve().parent.parent

MODULES: dict[str, tuple[str, tuple[str, ...]]] = {
    "losses": ("sb3_maddpg/common/losses.py", ("tests/common/test_losses.py",)),
    "selection": ("sb3_maddpg/common/selection.py", ("tests/common/test_selection.py",)),
    "buffers": ("sb3_maddpg/common/buffers.py", ("tests/common/test_buffers.py",)),
    "setting": (
        "sb3_maddpg/experiments/setting.py",
        (
            "tests/experiments/test_setting.py",
            "tests/experiments/test_cli_any_task.py",
            "tests/experiments/test_experiments.py",
        ),
    ),
    "matd3": ("sb3_maddpg/matd3/matd3.py", ("tests/matd3/test_matd3.py", "tests/matd3/test_matd3_defaults.py")),
    "evaluation": ("sb3_maddpg/analysis/evaluation.py", ("tests/analysis/test_evaluation.py",)),
}
"""The modules sampled and the test files each is run against."""

OPERATORS = {
    "<": "<=",
    "<=": "<",
    ">": ">=",
    ">=": ">",
    "==": "!=",
    "!=": "==",
    "+": "-",
    "-": "+",
    "*": "/",
    "/": "*",
    "//": "*",
}
NAMES = {"True": "False", "False": "True", "and": "or", "or": "and"}


@dataclass(frozen=True)
class Mutant:
    """One token of a source file replaced."""

    path: str
    """The file, relative to the repository root."""
    line: int
    """1-based."""
    column: int
    """0-based offset of the token in its line."""
    old: str
    new: str
    tests: tuple[str, ...]
    """The test files (or test ids) that should kill it."""

    def label(self) -> str:
        """:return: ``path:line: `old` -> `new```."""
        return f"{self.path}:{self.line}: `{self.old}` -> `{self.new}`"

    def mutate(self, source: str) -> tuple[str, str, str]:
        """:return: The mutated source, the original line and the mutated line; a ``ValueError`` if the token moved."""
        lines = source.splitlines(keepends=True)
        line = lines[self.line - 1]
        if line[self.column : self.column + len(self.old)] != self.old:
            raise ValueError(f"{self.label()}: the token is no longer there (the file changed)")
        mutated_line = line[: self.column] + self.new + line[self.column + len(self.old) :]
        lines[self.line - 1] = mutated_line
        return "".join(lines), line, mutated_line


def number_plus_one(text: str) -> str | None:
    """:return: The literal ``text`` plus one, written as Python would parse it, or None (complex, odd forms)."""
    try:
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return repr(value + 1)


def candidates(path: str, tests: tuple[str, ...]) -> list[Mutant]:
    """
    :param path: A module, relative to the repository root.
    :param tests: Its test files.
    :return: Every one-token mutant of its code that compiles.
    """
    source = (ROOT / path).read_text()
    found = []
    fstring_depth = 0
    fstring_start = getattr(tokenize, "FSTRING_START", None)  # Python 3.12+: f-strings are tokenised
    fstring_end = getattr(tokenize, "FSTRING_END", None)
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == fstring_start:
            fstring_depth += 1
        elif token.type == fstring_end:
            fstring_depth -= 1
        if fstring_depth:
            continue
        new = None
        if token.type == tokenize.OP:
            new = OPERATORS.get(token.string)
        elif token.type == tokenize.NUMBER:
            new = number_plus_one(token.string)
        elif token.type == tokenize.NAME:
            new = NAMES.get(token.string)
        if new is None:
            continue
        mutant = Mutant(path, token.start[0], token.start[1], token.string, new, tests)
        try:
            compile(mutant.mutate(source)[0], path, "exec")
        except SyntaxError:
            continue
        found.append(mutant)
    return found


LISTED: list[tuple[str, str, str, str, tuple[str, ...]]] = [
    (
        "sb3_maddpg/common/losses.py",
        "return (values * active).sum(dim=-2) / active.sum(dim=-2)",
        " / ",
        " * ",
        ("tests/common/test_losses.py::test_a_departed_agents_terms_are_the_mean_over_its_active_rows_only",),
    ),
    (
        "sb3_maddpg/common/selection.py",
        "return False",
        "False",
        "True",
        (
            "tests/common/test_selection.py::test_rules_that_need_no_positions_select_from_the_observations_on_an_env_that_reports_positions",
        ),
    ),
    (
        "sb3_maddpg/experiments/setting.py",
        "1_000_003 + 7919 * self.seed",
        "7919",
        "0",
        ("tests/experiments/test_setting.py::test_runs_of_different_seeds_are_evaluated_on_episodes_of_their_own",),
    ),
    (
        "sb3_maddpg/matd3/matd3.py",
        "tau: float = 0.01,",
        "0.01",
        "1.01",
        ("tests/matd3/test_matd3_defaults.py::test_matd3_has_maddpgs_defaults_and_td3s_own_from_sb3",),
    ),
    (
        "sb3_maddpg/matd3/matd3.py",
        "gamma: float = 0.95,",
        "0.95",
        "1.95",
        ("tests/matd3/test_matd3_defaults.py::test_matd3_has_maddpgs_defaults_and_td3s_own_from_sb3",),
    ),
    (
        "sb3_maddpg/matd3/matd3.py",
        "stats_window_size: int = 100,",
        "100",
        "101",
        ("tests/matd3/test_matd3_defaults.py::test_matd3_has_maddpgs_defaults_and_td3s_own_from_sb3",),
    ),
    (
        "sb3_maddpg/common/buffers.py",
        "if available is None or needed <= available // 2:",
        "<=",
        "<",
        ("tests/common/test_buffers.py::test_a_buffer_of_exactly_half_the_memory_is_quiet_and_one_byte_more_warns",),
    ),
    (
        "sb3_maddpg/common/buffers.py",
        "fitting = max(10 ** int(math.log10(max(available // 2 / per_transition, 1))), 1)",
        "available // 2",
        "available // 3",
        (
            "tests/common/test_buffers.py::test_the_suggested_buffer_size_is_the_largest_power_of_ten_that_fits_half_the_memory",
        ),
    ),
    (
        "sb3_maddpg/common/buffers.py",
        "fitting = max(10 ** int(math.log10(max(available // 2 / per_transition, 1))), 1)",
        "10 ** int",
        "11 ** int",
        (
            "tests/common/test_buffers.py::test_the_suggested_buffer_size_is_the_largest_power_of_ten_that_fits_half_the_memory",
        ),
    ),
    (
        "sb3_maddpg/common/buffers.py",
        "fitting = max(10 ** int(math.log10(max(available // 2 / per_transition, 1))), 1)",
        "/ per_transition",
        "* per_transition",
        (
            "tests/common/test_buffers.py::test_the_suggested_buffer_size_is_the_largest_power_of_ten_that_fits_half_the_memory",
        ),
    ),
    (
        "sb3_maddpg/common/buffers.py",
        "fitting = max(10 ** int(math.log10(max(available // 2 / per_transition, 1))), 1)",
        "1))), 1)",
        "1))), 2)",
        (
            "tests/common/test_buffers.py::test_the_suggested_buffer_size_is_the_largest_power_of_ten_that_fits_half_the_memory",
        ),
    ),
    (
        "sb3_maddpg/common/losses.py",
        "saturated = ((policy_actions.abs() > SATURATION_THRESHOLD) & parts.continuous).float()\n",
        ">",
        ">=",
        ("tests/common/test_losses.py::test_an_action_at_the_saturation_threshold_is_not_saturated_and_one_just_above_is",),
    ),
    (
        "sb3_maddpg/experiments/setting.py",
        "elif neighbors >= experiment.n_agents - 1:",
        ">=",
        ">",
        (
            "tests/experiments/test_setting.py::test_observing_every_other_agent_is_described_as_full_observability_nearest_first",
        ),
    ),
    (
        "sb3_maddpg/analysis/evaluation.py",
        "n_eval_episodes: int = 100,",
        "100",
        "101",
        ("tests/analysis/test_evaluation.py::test_the_callback_evaluates_the_papers_100_episodes_by_default",),
    ),
]
"""Issue 59's eleven survivors: the file, the text of the line (unique in it), the token, its mutant and the test
that kills it. Lines are found by their text, since line numbers drift. The issue does not say which operator of the
suggested ``buffer_size``'s line survived: four one-token changes of it are listed."""


FIRST_DRAW: list[tuple[str, str, str, str]] = [
    ("buffers", "rows = max(buffer_size // n_envs, 1) * n_envs", "1)", "2)"),
    ("buffers", "return int(line.split()[1]) * 1024", "[1]", "[2]"),
    ("evaluation", "        deterministic: bool = True,", "True", "False"),
    ("evaluation", "if self.verbose >= 1:", ">=", ">"),
    ("losses", "reg = reg_coef * _mean_over_rows(preactivations.pow(2)", "2", "3"),
    ("losses", "reg_coef > 0 else th.zeros_like(policy_loss)", "0 else", "1 else"),
    ("selection", "if self.k > layout.n_agents - 1:", "- 1", "- 2"),
    ("selection", 'return self.target == "next" and', "==", "!="),
    ("setting", "if self.n_agents < 1 or", "< 1", "< 2"),
]
"""The survivors of a first draw (``--seed 59`` with one generator for all modules, before the draw became per
module): the module, the text of the line, the token and its mutant; each is run against its module's test files."""


def listed_mutants(first_draw: bool = False) -> list[Mutant]:
    """:return: :data:`LISTED` (or :data:`FIRST_DRAW`) located in today's files."""
    mutants = []
    listed = [(MODULES[name][0], text, old, new, MODULES[name][1]) for name, text, old, new in FIRST_DRAW]
    for path, text, old, new, tests in listed if first_draw else LISTED:
        lines = (ROOT / path).read_text().splitlines(keepends=True)
        matches = [i for i, line in enumerate(lines) if text in line]
        if len(matches) != 1:
            raise ValueError(f"{path}: {len(matches)} lines hold {text!r}, expected 1")
        line = lines[matches[0]]
        column = line.index(text) + text.index(old)
        mutants.append(Mutant(path, matches[0] + 1, column, old, new, tests))
    return mutants


def write_atomically(path: Path, text: str) -> None:
    """Replace ``path``'s content at once (a reader never sees half a file), keeping its mode."""
    tmp = path.with_name(f".{path.name}.mutation.tmp")
    tmp.write_text(text)
    os.chmod(tmp, path.stat().st_mode)
    os.replace(tmp, path)


@contextlib.contextmanager
def applied(mutant: Mutant) -> Iterator[None]:
    """Within: ``mutant`` is in its file. On leaving, however it is left, its line is put back."""
    path = ROOT / mutant.path
    original = path.read_text()
    mutated, line, mutated_line = mutant.mutate(original)
    write_atomically(path, mutated)
    written_at = int(path.stat().st_mtime)
    try:
        yield
    finally:
        while int(time.time()) <= written_at:  # a .pyc of the mutant is keyed on (mtime in seconds, size)
            time.sleep(0.2)
        current = path.read_text()
        if current == mutated:
            write_atomically(path, original)
        elif current != original:  # someone edited the file meanwhile: put back only the mutated line
            lines = current.splitlines(keepends=True)
            where = [i for i, text in enumerate(lines) if text == mutated_line]
            if len(where) != 1:
                raise RuntimeError(f"{mutant.label()}: could not restore the line, restore it by hand: {line!r}")
            lines[where[0]] = line
            write_atomically(path, "".join(lines))


def pytest_command(tests: tuple[str, ...], deselect: list[str], stop_at_first: bool = True) -> list[str]:
    """:return: The command that runs ``tests`` (quick lane), ``deselect`` left out."""
    command = [sys.executable, "-m", "pytest", "-q", "-m", "not slow", "-p", "no:cacheprovider", "-rf", *tests]
    if stop_at_first:
        command.insert(3, "-x")
    for test in deselect:
        command += ["--deselect", test]
    return command


def run(command: list[str], timeout: float) -> tuple[int | None, str]:
    """:return: The exit status (None on a timeout; the process group is killed) and the output."""
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    process = subprocess.Popen(
        command, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    try:
        output, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        output, _ = process.communicate()
        return None, output
    return process.returncode, output


def baseline_failures(tests: tuple[str, ...], timeout: float) -> list[str]:
    """:return: The test ids that fail before any mutation (to deselect); a ``RuntimeError`` if the files cannot run."""
    status, output = run(pytest_command(tests, [], stop_at_first=False), timeout)
    if status not in (0, 1):
        raise RuntimeError(f"the baseline of {tests} did not run (status {status}):\n{output[-3000:]}")
    return re.findall(r"^FAILED (\S+)", output, flags=re.MULTILINE)


def verdict(mutant: Mutant, deselect: list[str], timeout: float) -> tuple[str, str]:
    """:return: ``"killed"``, ``"killed (timeout)"`` or ``"survived"``, and the first failure's summary line (what
    killed it: a failed assertion, not a test file that no longer imports)."""
    with applied(mutant):
        status, output = run(pytest_command(mutant.tests, deselect), timeout)
    if status is None:
        return "killed (timeout)", ""
    if status == 0:
        return "survived", ""
    failures = re.findall(r"^(?:FAILED|ERROR) .*$", output, flags=re.MULTILINE)
    return "killed", (failures[0] if failures else output.strip()[-300:])


def stop_on_term(signum: int, frame: FrameType | None) -> None:
    """SIGTERM as an exception, so that the current mutant's ``finally`` restores its file."""
    raise SystemExit(f"stopped by signal {signum}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modules", nargs="+", choices=sorted(MODULES), default=sorted(MODULES))
    parser.add_argument("--per-module", type=int, default=6, help="mutants drawn per module")
    parser.add_argument("--seed", type=int, default=59)
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per test run")
    parser.add_argument("--only", nargs="+", default=(), help="run only the drawn mutants at these file:line")
    parser.add_argument("--listed", action="store_true", help="issue 59's survivors, each against its new test")
    parser.add_argument("--first-draw", action="store_true", help="the first draw's survivors, against their modules' tests")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, stop_on_term)

    plan: list[tuple[Mutant, list[str]]] = []
    if args.listed or args.first_draw:
        plan = [(mutant, []) for mutant in listed_mutants(args.first_draw)]
    else:
        for name in args.modules:
            path, tests = MODULES[name]
            found = candidates(path, tests)
            rng = random.Random(f"{args.seed}:{name}")
            drawn = sorted(rng.sample(found, min(args.per_module, len(found))), key=lambda m: (m.line, m.column))
            if args.only:
                drawn = [m for m in drawn if any(f"{m.path}:{m.line}".endswith(where) for where in args.only)]
                if not drawn:
                    continue
            deselect = baseline_failures(tests, args.timeout)
            print(f"{path}: {len(found)} candidates, {len(drawn)} drawn; baseline failures: {deselect or 'none'}", flush=True)
            plan += [(mutant, deselect) for mutant in drawn]

    rows = []
    for mutant, deselect in plan:
        started = time.monotonic()
        result, why = verdict(mutant, deselect, args.timeout)
        print(f"{result:17} {mutant.label()}  ({time.monotonic() - started:.0f} s)", flush=True)
        if why:
            print(f"{'':17} {why[:300]}", flush=True)
        rows.append((mutant, result))
    killed = sum(result.startswith("killed") for _, result in rows)
    print(f"\n{killed} of {len(rows)} killed\n")
    print("| mutant | tests | result |\n|---|---|---|")
    for mutant, result in rows:
        print(f"| {mutant.label()} | {', '.join(mutant.tests)} | {result} |")


if __name__ == "__main__":
    main()
