"""Code lines of the package, by folder: lines that hold code, not docstrings, comments or blank lines (tokenize's
view). Issue 58's limits: ``experiments/`` (with its presets) at most 3,000, the package at most 10,000.

Usage: ``python benchmarks/code_size.py [PACKAGE_DIR]`` (default ``sb3_maddpg``).
"""

import sys
import tokenize
from pathlib import Path

SKIPPED = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.ENCODING, tokenize.INDENT, tokenize.DEDENT}
STATEMENT_STARTS = {tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT}


def code_lines(path: Path) -> int:
    """:return: The lines of ``path`` that hold a token of code (a string alone as a statement is a docstring)."""
    with open(path, "rb") as file:
        tokens = [token for token in tokenize.tokenize(file.readline) if token.type != tokenize.ENDMARKER]
    lines: set[int] = set()
    previous = tokenize.NEWLINE
    for index, token in enumerate(tokens):
        if token.type in SKIPPED:
            previous = token.type if token.type in STATEMENT_STARTS else previous
            continue
        if token.type == tokenize.STRING and previous in STATEMENT_STARTS:
            following = next((t for t in tokens[index + 1 :] if t.type not in (tokenize.COMMENT, tokenize.NL)), None)
            if following is None or following.type == tokenize.NEWLINE:
                previous = tokenize.STRING
                continue
        previous = token.type
        lines.update(range(token.start[0], token.end[0] + 1))
    return len(lines)


def folder_sizes(package: Path) -> dict[str, int]:
    """:return: Code lines per top-level folder of ``package`` (its subfolders counted in), ``.`` for its own files."""
    sizes: dict[str, int] = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package).parts
        folder = parts[0] if len(parts) > 1 else "."
        sizes[folder] = sizes.get(folder, 0) + code_lines(path)
    return sizes


def main(package: Path) -> None:
    sizes = folder_sizes(package)
    width = max(map(len, sizes))
    for folder, lines in sorted(sizes.items(), key=lambda item: -item[1]):
        print(f"{folder:<{width}}  {lines:>6,}")
    print(f"{'total':<{width}}  {sum(sizes.values()):>6,}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "sb3_maddpg"))
