"""The study's runner stays small (issue 58): ``experiments/``, with its presets, at most 3,000 code lines, counted
by ``benchmarks/code_size.py`` (no docstrings, comments or blank lines)."""

from pathlib import Path
from types import ModuleType

from tests.script_module import load_script

REPO = Path(__file__).resolve().parent.parent
EXPERIMENTS_LIMIT = 3_000


def code_size() -> ModuleType:
    return load_script(REPO / "benchmarks" / "code_size.py")


def test_the_experiments_package_is_at_most_its_limit() -> None:
    sizes = code_size().folder_sizes(REPO / "sb3_maddpg")
    assert 1_000 < sizes["experiments"] <= EXPERIMENTS_LIMIT, sizes["experiments"]


def test_docstrings_comments_and_blank_lines_are_not_code(tmp_path: Path) -> None:
    source = tmp_path / "module.py"
    lines = [
        '"""Doc',
        'string."""',
        "",
        "# a comment",
        "x = 1  # why",
        "",
        "def f():",
        '    """Doc."""',
        "    return (",
        '        "a"',
        "    )",
    ]
    source.write_text("\n".join(lines) + "\n")
    assert code_size().code_lines(source) == 5  # x, def, return ( "a" )
