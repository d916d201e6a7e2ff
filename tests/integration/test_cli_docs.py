"""The command-line page tells the truth: its help texts are what ``--help`` prints.

``docs/guide/cli.md``'s section "Every subcommand's ``--help``" is written by
``python -m jaxproj.cli.docs`` (at ``COLUMNS=100``); these tests compare it with what the
command prints for ``--help`` at that width, and check that the page's hand-written synopsis
names every option. When they fail: run ``python -m jaxproj.cli.docs`` (and, for a new option,
add it to the synopsis).
"""

from __future__ import annotations

import argparse
import re

import pytest

from jaxproj.cli import docs, main

PAGE = docs.DOC_PATH
HEADING = re.compile(
    r"^### `(jaxproj(?: [a-z]+)?)`\n\n```text\n(.*?)^```$", re.DOTALL | re.MULTILINE
)


def _page() -> str:
    return PAGE.read_text(encoding="utf-8")


def _generated(page: str) -> str:
    start, stop = page.index(docs.BEGIN), page.index(docs.END)
    return page[start:stop]


def _printed_help(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--help"])
    assert stop.value.code == 0
    return capsys.readouterr().out


def test_page_help_blocks_are_what_help_prints(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", str(docs.COLUMNS))
    monkeypatch.setenv("NO_COLOR", "1")
    blocks = dict(HEADING.findall(_generated(_page())))
    want = ["jaxproj", *(f"jaxproj {name}" for name in docs.subcommands())]
    assert list(blocks) == want, "run `python -m jaxproj.cli.docs`: the page's commands differ"
    stale = [
        title for title, text in blocks.items() if text != _printed_help(title.split()[1:], capsys)
    ]
    assert not stale, (
        f"docs/guide/cli.md: --help of {stale} differs; run python -m jaxproj.cli.docs"
    )


def test_generator_writes_the_page_as_it_is() -> None:
    page = _page()
    assert docs.render(page) == page, "run `python -m jaxproj.cli.docs`"
    assert docs.main(["--check"]) == 0


def test_generator_replaces_only_between_the_markers() -> None:
    page = f"# Title\n\nbefore\n\n{docs.BEGIN}\nold text\n{docs.END}\n\nafter\n"
    new = docs.render(page)
    assert new.startswith("# Title\n\nbefore\n\n" + docs.BEGIN)
    assert new.endswith(docs.END + "\n\nafter\n")
    assert "old text" not in new and "### `jaxproj retarget`" in new
    assert docs.render(new) == new  # idempotent
    with pytest.raises(ValueError, match="needs the lines"):
        docs.render("# no markers\n")


def _synopsis_of(command: str, page: str) -> str:
    """The synopsis lines of ``jaxproj COMMAND`` (its first line and the indented ones after)."""
    block = page[page.index("## Synopsis") :]
    block = block[block.index("```bash\n") + 8 :]
    block = block[: block.index("```")]
    lines = block.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith(f"jaxproj {command} "))
    out = [lines[first]]
    for line in lines[first + 1 :]:
        if not line.startswith(" "):
            break
        out.append(line)
    return "\n".join(out)


def test_synopsis_names_every_option() -> None:
    page = _page()
    missing = []
    for name, parser in docs.subcommands().items():
        synopsis = _synopsis_of(name, page)
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction) or not action.option_strings:
                continue
            if not any(
                re.search(rf"{re.escape(o)}(?![\w-])", synopsis) for o in action.option_strings
            ):
                missing.append(f"{name} {action.option_strings[0]}")
    assert not missing, f"docs/guide/cli.md's synopsis lacks {missing}"


def test_synopsis_lists_every_choice() -> None:
    """An option with fixed choices shows them all, in the parser's order (``--format a|b|c``)."""
    page = _page()
    wrong = []
    for name, parser in docs.subcommands().items():
        synopsis = _synopsis_of(name, page)
        for action in parser._actions:
            if not action.option_strings or not action.choices:
                continue
            want = "|".join(str(c) for c in action.choices)
            for o in action.option_strings:
                for shown in re.findall(rf"{re.escape(o)} ([\w|+-]+)", synopsis):
                    if shown != want:
                        wrong.append(f"{name} {o} {shown} (parser: {want})")
    assert not wrong, f"docs/guide/cli.md's synopsis lists other choices: {wrong}"
