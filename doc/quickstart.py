"""Run the README's Quickstart as a new user would, and check (or refresh) what it shows.

The Quickstart (the README section between ``## Quickstart`` and the next ``## ``) holds

- ``console`` blocks: ``$ COMMAND`` lines, each followed by what it prints on stdout. A
  line ``...`` stands for any number of lines (the excerpt of a long output);
- ``bash`` blocks: commands (one per line, ``# comments`` allowed), run, output not shown;
- ``python`` blocks: run as a script.

Everything runs in order, in a folder holding what a fresh clone holds that the commands
read (``data_synth/``), with this tree's package. Usage, from the repository root::

    python doc/quickstart.py            # run it all; exit 1 and show the differences if any
    python doc/quickstart.py --update   # run it all and write the outputs into README.md

``tests/project/test_quickstart.py`` runs the check.
"""

from __future__ import annotations

import difflib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: What a fresh clone holds that the Quickstart's commands read.
NEEDED = ("data_synth",)
ELLIPSIS = "..."
_FENCE = re.compile(r"^```(\w*)\s*$")


@dataclass
class Step:
    """One thing the Quickstart runs: a shell command (with its shown output) or a script."""

    kind: str  # "console", "bash" or "python"
    text: str  # the command line, or the script
    shown: list[str] | None = None  # console: the output lines shown
    where: tuple[int, int] = (0, 0)  # console: README lines of the shown output [a, b)
    got: list[str] = field(default_factory=list)


def section(text: str) -> tuple[int, int]:
    """Line range ``[a, b)`` of the Quickstart section in the README's lines."""
    lines = text.splitlines()
    a = lines.index("## Quickstart")
    b = next(k for k in range(a + 1, len(lines)) if lines[k].startswith("## "))
    return a, b


def steps(text: str) -> list[Step]:
    """The steps of the Quickstart, in order."""
    lines = text.splitlines()
    a, b = section(text)
    out: list[Step] = []
    k = a
    while k < b:
        m = _FENCE.match(lines[k])
        if not m or not m.group(1):
            k += 1
            continue
        kind, body, k = m.group(1), [], k + 1
        start = k
        while not lines[k].startswith("```"):
            body.append(lines[k])
            k += 1
        k += 1
        if kind == "python":
            out.append(Step("python", "\n".join(body) + "\n"))
        elif kind == "bash":
            for line in body:
                cmd = line.split(" #", 1)[0].strip()
                if cmd and not cmd.startswith("#"):
                    out.append(Step("bash", cmd))
        elif kind == "console":
            for j, line in enumerate(body):
                if line.startswith("$ "):
                    end = next(
                        (i for i in range(j + 1, len(body)) if body[i].startswith("$ ")),
                        len(body),
                    )
                    out.append(
                        Step(
                            "console",
                            line[2:],
                            [x.rstrip() for x in body[j + 1 : end]],
                            (start + j + 1, start + end),
                        )
                    )
    return out


def matches(shown: list[str], got: list[str]) -> bool:
    """Whether ``got`` fits ``shown``, where a line ``...`` stands for any lines.

    Examples
    --------
    >>> matches(["a", "...", "d"], ["a", "b", "c", "d"]), matches(["a", "..."], ["b"])
    (True, False)
    """
    if ELLIPSIS not in shown:
        return shown == got
    chunks: list[list[str]] = [[]]
    for line in shown:
        if line == ELLIPSIS:
            chunks.append([])
        else:
            chunks[-1].append(line)
    first, *middle, last = chunks
    if got[: len(first)] != first or len(got) < len(first) + len(last):
        return False
    end = len(got) - len(last)
    if last and got[end:] != last:
        return False
    pos = len(first)
    for chunk in middle:
        while pos + len(chunk) <= end and got[pos : pos + len(chunk)] != chunk:
            pos += 1
        if pos + len(chunk) > end:
            return False
        pos += len(chunk)
    return True


def _prefix(line: str) -> str:
    return re.split(r"\d", line, maxsplit=1)[0]


def excerpt(shown: list[str], got: list[str]) -> list[str]:
    """``got`` cut as ``shown`` is: the same first and last lines, and each shown stretch
    between ``...`` lines where its first line is now (the same text up to its first digit).

    A shown output of ``...`` alone is a placeholder: all of ``got``.

    Examples
    --------
    >>> excerpt(["a 1", "...", "rms 0.5", "...", "end"], ["a 2", "x", "rms 0.4", "y", "end"])
    ['a 2', '...', 'rms 0.4', '...', 'end']
    """
    if ELLIPSIS not in shown or shown == [ELLIPSIS]:
        return list(got)
    chunks: list[list[str]] = [[]]
    for line in shown:
        if line == ELLIPSIS:
            chunks.append([])
        else:
            chunks[-1].append(line)
    first, *middle, last = chunks
    out = list(got[: len(first)])
    pos = len(first)
    for chunk in middle:
        j = next((i for i in range(pos, len(got)) if got[i] == chunk[0]), None)
        if j is None:
            j = next(
                (i for i in range(pos, len(got)) if _prefix(got[i]) == _prefix(chunk[0])), None
            )
        if j is None:
            continue
        out += [ELLIPSIS, *got[j : j + len(chunk)]]
        pos = j + len(chunk)
    out += [ELLIPSIS, *(got[len(got) - len(last) :] if last else [])]
    return out


def run(all_steps: list[Step], workdir: Path, env: dict[str, str] | None = None) -> None:
    """Run the steps in ``workdir`` (a copy of :data:`NEEDED` is made there); fill ``got``.

    Raises
    ------
    RuntimeError
        When a step exits with a status other than 0 (its command, status and stderr).
    """
    for name in NEEDED:
        shutil.copytree(ROOT / name, workdir / name, dirs_exist_ok=True)
    env = dict(os.environ if env is None else env)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    # the console script of this interpreter's environment
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    for step in all_steps:
        if step.kind == "python":
            cmd = [sys.executable, "-c", step.text]
            shown = "python block"
        else:
            cmd = ["bash", "-c", step.text]
            shown = step.text
            if shutil.which("hystdisc", path=env["PATH"]) is None:  # not installed
                cmd = [
                    "bash",
                    "-c",
                    re.sub(r"^hystdisc ", f"{sys.executable} -m hystdisc ", step.text),
                ]
        proc = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(
                f"the Quickstart's {shown!r} exited with {proc.returncode}:\n{proc.stderr[-3000:]}"
            )
        step.got = [line.rstrip() for line in proc.stdout.splitlines()]


def differences(all_steps: list[Step]) -> list[str]:
    """A unified diff per console step whose output does not fit what is shown."""
    out = []
    for s in all_steps:
        if s.kind == "console" and not matches(s.shown or [], s.got):
            diff = difflib.unified_diff(
                s.shown or [], excerpt(s.shown or [], s.got), "README", "now", lineterm=""
            )
            out.append(f"$ {s.text}\n" + "\n".join(diff))
    return out


def update(text: str, all_steps: list[Step]) -> str:
    """The README text with each console step's shown output replaced by what it printed."""
    lines = text.splitlines()
    for s in sorted(
        (s for s in all_steps if s.kind == "console"), key=lambda s: -s.where[0]
    ):  # from the bottom, so that the line numbers above stay right
        a, b = s.where
        lines[a:b] = excerpt(s.shown or [], s.got)
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python doc/quickstart.py [--update]``."""
    argv = sys.argv[1:] if argv is None else argv
    text = README.read_text(encoding="utf-8")
    all_steps = steps(text)
    with tempfile.TemporaryDirectory() as tmp:
        run(all_steps, Path(tmp))
    if "--update" in argv:
        README.write_text(update(text, all_steps), encoding="utf-8")
        print(f"updated the Quickstart outputs in {README}")
        return 0
    diffs = differences(all_steps)
    for d in diffs:
        print(d)
    print(f"{len(all_steps)} steps run; {len(diffs)} outputs differ from the README")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
