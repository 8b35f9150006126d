"""Every command the documentation shows runs: each ``quadrs ...`` line of a ```bash / ```sh
block (and each ``$ quadrs ...`` or ``$ python -c ...`` line of any block) in README.md and
docs/*.md is run as a user would paste it, with its run counts lowered, and the test fails
naming the page and the command when one exits other than it says it does. A page cannot go
stale against the program silently again.

A command may read a file the page only names (``mine.toml``, ``my-delivery.plan``) or that an
earlier command of the page wrote (``runs.parquet``): those are made here (:data:`FILES`);
a ```toml block right after a paragraph naming ``name.toml`` is the file of that name.
A command that is documented to exit other than 0 is in :data:`EXPECTED_EXIT`, one that cannot
run here in :data:`NOT_RUN`, each with the reason; the expensive ones are marked slow."""

from __future__ import annotations

import json
import re
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: Each option that sets a run count, and the value it is lowered to.
LOWERED = {
    "--runs": "2",
    "--per-level": "20",
    "--maxiter": "1",
    "--popsize": "1",
    "--sweep-runs": "2",
}
#: Per command: options lowered to another value (a power of two for Saltelli's design), or
#: added when the command leaves them at a default too costly here.
LOWERED_FOR = {
    "sensitivity": {"--runs": "4"},
    "tune": {"--runs": "2", "--maxiter": "1", "--popsize": "1"},
    "rare": {"--per-level": "20", "--p0": "0.5", "--max-levels": "2"},
    "paper": {"--runs": "2", "--sweep-runs": "2"},
}

#: (page, the command's start) -> the exit status the page documents, and where it says so.
EXPECTED_EXIT = {
    # "exit 1 if unstable": the paper's SMC lateral gains are (README, "Presets").
    ("README.md", "quadrs stability --preset paper"): 1,
    # "finds no candidate that meets the second constraint, says so and exits 1": the whole
    # flight's max_accel is the touchdown contact's (delivery.md, section 6).
    ("delivery.md", "quadrs tune --preset delivery"): 1,
}
#: (page, the command's start) -> why it is not run here.
NOT_RUN = {
    ("README.md", "quadrs mc --runs 20000 --scheduler"): "needs a Dask cluster at its address",
}
#: Commands that take tens of seconds even lowered (the reason beside each), by their start
#: or an option they give: marked slow (scripts/test.sh --slow runs them).
EXPENSIVE = {
    "quadrs paper": "every table and figure: a sweep over 5 frequencies and 3 masses",
    "quadrs tune --preset delivery": "a tuning of the 211 s delivery route",
    "quadrs rare --metric": "subset simulation over the paper's whole 80 s flights",
    "--plot": "draws and writes every figure (PNG and SVG): 10-30 s of matplotlib",
}


def expensive(command: DocCommand) -> str | None:
    """Why ``command`` is slow, or None."""
    words = command.text.split()
    for what, why in EXPENSIVE.items():
        if command.text.startswith(what) or (what.startswith("--") and any(
                w == what or w.startswith(f"{what}s") for w in words)):  # fmt: skip
            return why
    return None


#: A scenario of the paper preset with one change, as ``mine.toml`` in the README.
_MINE = 'base = "paper"\n\n[payload]\nmass = 0.3\n'
#: A short delivery route (two legs at 5 m), as a user's ``my-route.toml`` (its duration and
#: turbulence follow the route, as the preset's do).
_MY_ROUTE = """base = "delivery"

[initial]
position = [0.0, 0.0, 5.0]

[trajectory]
route = [[0.0, 0.0, 5.0], [30.0, 0.0, 5.0], [30.0, 10.0, 5.0]]
hold = [0.0, 0.0, 1.0]
lower = [0.0, 0.0, 0.0]
names = ["out", "across", "drop"]
"""
_HOME = (47.3977419, 8.5455938, 488.0)


def _plan() -> str:
    """A QGroundControl .plan: take off to 20 m, 50 m north, land."""
    north = 50.0 / 111_200.0

    def item(command: int, lat: float | None, lon: float | None, alt: float) -> dict:
        return {"type": "SimpleItem", "command": command, "frame": 3, "autoContinue": True,
                "params": [0, 0, 0, None, lat, lon, alt]}  # fmt: skip

    lat, lon = _HOME[0], _HOME[1]
    items = [item(22, None, None, 20.0), item(16, lat, lon, 20.0),
             item(16, lat + north, lon, 20.0), item(21, lat + north, lon, 0.0)]  # fmt: skip
    return json.dumps({
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "mission": {"version": 2, "firmwareType": 12, "vehicleType": 2, "cruiseSpeed": 8,
                    "hoverSpeed": 5, "plannedHomePosition": list(_HOME), "items": items},
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
    })  # fmt: skip


#: Files a page names without giving them: name -> text (None: made by :func:`_made_file`).
FILES: dict[str, str | None] = {
    "mine.toml": _MINE,
    "my-route.toml": _MY_ROUTE,
    "my-delivery.plan": _plan(),
    "points.csv": "x,y,z\n0,0,5\n40,0,5\n40,20,5\n",
    "delivery-tuned.toml": 'base = "delivery"\n\n[controller.pd]\nkp = [1.1, 1.1, 1.5]\n',
    "runs.parquet": None,
}


@dataclass(frozen=True)
class DocCommand:
    """One command a page shows: the page's name, its line, the words as pasted."""

    page: str
    line: int
    text: str

    def __str__(self) -> str:
        return f"{self.page}:{self.line}: {self.text}"


def _fences(text: str) -> list[tuple[str, int, list[str], str]]:
    """Each fenced block: its language, first line number, its lines, the paragraph before."""
    blocks, lines = [], text.splitlines()
    i = 0
    while i < len(lines):
        m = re.match(r"^\s*```(\S*)\s*$", lines[i])
        if not m:
            i += 1
            continue
        start, body = i + 1, []
        i += 1
        while i < len(lines) and not re.match(r"^\s*```\s*$", lines[i]):
            body.append(lines[i])
            i += 1
        end = start - 1
        while end > 0 and not lines[end - 1].strip():
            end -= 1
        j = end - 1
        while j >= 0 and lines[j].strip():  # the paragraph before the block
            j -= 1
        before = " ".join(lines[j + 1 : end])
        blocks.append((m.group(1), start + 1, body, before))
        i += 1
    return blocks


def _joined(body: list[str]) -> list[tuple[int, str]]:
    """The block's lines with backslash continuations joined: (offset, line)."""
    out, i = [], 0
    while i < len(body):
        at, line = i, body[i]
        while line.rstrip().endswith("\\") and i + 1 < len(body):
            i += 1
            line = line.rstrip()[:-1] + " " + body[i].strip()
        out.append((at, line))
        i += 1
    return out


def doc_commands(page: Path) -> list[DocCommand]:
    """The commands ``page`` shows: ``quadrs`` lines of shell blocks, ``$ quadrs`` and
    ``$ python -c`` lines of any block."""
    found = []
    for lang, first, body, _ in _fences(page.read_text()):
        for offset, line in _joined(body):
            s = line.strip()
            if s.startswith("$ "):
                s = s[2:].strip()
                s = s.removeprefix("time ").strip()
                if not (s.startswith("quadrs ") or s.startswith("python -c ")):
                    continue
            elif lang not in ("bash", "sh", "shell") or not s.startswith("quadrs "):
                continue
            found.append(DocCommand(page.name, first + offset, s))
    return found


def named_files(page: Path) -> dict[str, str]:
    """The ```toml blocks a page names: the block right after a paragraph that names a
    ```x.toml``` (the last it names)."""
    files = {}
    for lang, _, body, before in _fences(page.read_text()):
        names = re.findall(r"`([\w.-]+\.toml)`", before)
        if lang == "toml" and names:
            files[names[-1]] = "\n".join(body) + "\n"
    return files


def argv_of(command: DocCommand) -> list[str]:
    """The command's words, without ``quadrs``, its comment and its ``[optional]`` parts,
    with its run counts lowered."""
    text = re.sub(r"\s\[[^\]]*\]", "", command.text)  # "[--resume]" is optional
    words = shlex.split(text, comments=True)
    words = words[1:]
    own = LOWERED_FOR.get(words[0] if words else "", {})
    lowered = {**LOWERED, **own}
    for i, w in enumerate(words[:-1]):
        if w in lowered:
            words[i + 1] = lowered[w]
    return words + [x for option, value in own.items() if option not in words
                    for x in (option, value)]  # fmt: skip


def _key(command: DocCommand, table: dict[tuple[str, str], object]) -> tuple[str, str] | None:
    for page, start in table:
        if page == command.page and command.text.startswith(start):
            return page, start
    return None


def _params() -> list[object]:
    params = []
    for page in PAGES:
        for c in doc_commands(page):
            marks = []
            key = _key(c, NOT_RUN)
            if key is not None:
                marks.append(pytest.mark.skip(reason=NOT_RUN[key]))
            if expensive(c) is not None:
                marks.append(pytest.mark.slow)
            params.append(pytest.param(c, id=f"{c.page}:{c.line}", marks=marks))
    return params


def _made_file(name: str, folder: Path) -> None:
    from quadrs.cli.main import main

    if name == "runs.parquet":
        assert main(["mc", "--runs", "2", "--no-progress", "--out", str(folder / name)]) == 0


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """Every file a page's commands read, made once."""
    folder = tmp_path_factory.mktemp("doc-inputs")
    made = {}
    for name, text in FILES.items():
        if text is None:
            _made_file(name, folder)
            made[name] = (folder / name).read_bytes()
        else:
            made[name] = text.encode()
    for page in PAGES:
        made.update({n: t.encode() for n, t in named_files(page).items()})
    return made


def run_doc_command(command: DocCommand, folder: Path, capsys: pytest.CaptureFixture[str]) -> int:
    """Run one command in ``folder`` as the page shows it (its run counts lowered); its exit
    status."""
    if command.text.startswith("python -c "):
        import subprocess

        words = shlex.split(command.text, comments=True)
        proc = subprocess.run([sys.executable, *words[1:]], cwd=folder, capture_output=True,
                              text=True, timeout=300, check=False)  # fmt: skip
        print(proc.stdout, proc.stderr)
        return proc.returncode
    from quadrs.cli.main import main

    return main(argv_of(command))


@pytest.mark.parametrize("command", _params())
def test_a_documented_command_runs(
    command: DocCommand,
    inputs: dict[str, bytes],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    for name, data in inputs.items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / "docs" / "figures").mkdir(parents=True)  # a figure a page redraws
    monkeypatch.chdir(tmp_path)
    key = _key(command, EXPECTED_EXIT)
    expected = EXPECTED_EXIT[key] if key is not None else 0
    try:
        code = run_doc_command(command, tmp_path, capsys)
    except SystemExit as e:  # argparse refused the words
        code = e.code if isinstance(e.code, int) else 2
    out, err = capsys.readouterr()
    assert code == expected, (
        f"{command}\n  ran as: quadrs {' '.join(argv_of(command))}\n  exit {code}, the page "
        f"says {expected}\n{err[-2000:]}\n{out[-1000:]}"
    )


def test_the_commands_are_found() -> None:
    """The parser finds the commands of each kind of block (a parser that found none would
    pass every page)."""
    readme = [c.text for c in doc_commands(ROOT / "README.md")]
    assert any(t.startswith("quadrs mission --runs 200") for t in readme)
    assert not any(t.startswith("quadrs") and "\\" in t for t in readme)  # continuations joined
    rare = [c.text for c in doc_commands(ROOT / "docs" / "rare-events.md")]
    assert any(t.startswith("quadrs rare --scenario short-gust.toml") for t in rare)
    assert "short-gust.toml" in named_files(ROOT / "docs" / "rare-events.md")
    words = argv_of(DocCommand("x", 1, "quadrs mc --runs 20000 --checkpoint runs/ [--resume]  # x"))
    assert words == ["mc", "--runs", "2", "--checkpoint", "runs/"]
