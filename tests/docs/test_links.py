"""Docs that stay true: every Markdown link and anchor in README.md and docs/ resolves, and so does every
`docs/<page>.md#<anchor>` the code points to (anchors as GitHub renders headings)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"!?\[([^\]]*)\]\(\s*([^)\s]+)(?:\s+\"[^\"]*\")?\s*\)")
CODE_REF = re.compile(r"\bdocs/([\w.-]+\.md)#([\w-]+)")


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: markup dropped, lower case, punctuation but '-' and '_' removed, spaces to '-'."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's text
    text = text.replace("`", "").strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def prose(text: str) -> str:
    """The text outside fenced code blocks and inline code spans."""
    text = re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def anchors(page: Path) -> set[str]:
    out: set[str] = set()
    seen: dict[str, int] = {}
    for m in re.finditer(r"^#{1,6}\s+(.+?)\s*#*\s*$", prose(page.read_text()), re.M):
        s = slug(m.group(1))
        n = seen.get(s, 0)
        out.add(s if n == 0 else f"{s}-{n}")
        seen[s] = n + 1
    out |= set(re.findall(r"<a\s+(?:name|id)=\"([^\"]+)\"", page.read_text()))
    return out


def test_slug_is_githubs():
    assert slug("Linear stability") == "linear-stability"
    assert slug("The `hil` loop: 2 kHz (ticks)") == "the-hil-loop-2-khz-ticks"
    assert slug("Speed against accuracy") == "speed-against-accuracy"


def links():
    for page in PAGES:
        for m in LINK.finditer(prose(page.read_text())):
            yield page, m.group(2)


@pytest.mark.parametrize("page,target", list(links()), ids=lambda v: str(v).replace(str(ROOT) + "/", ""))
def test_markdown_link_resolves(page, target):
    if re.match(r"[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto: ... are not checked offline
        return
    path, _, anchor = target.partition("#")
    dest = (page.parent / path).resolve() if path else page
    assert dest.exists(), f"{page.name}: link to {target}: {dest} does not exist"
    if anchor:
        assert dest.suffix == ".md", f"{page.name}: anchor #{anchor} on a non-Markdown target {dest.name}"
        assert anchor in anchors(dest), f"{page.name}: {target}: no heading with anchor #{anchor} in {dest.name}"


def code_refs():
    for base in ("host_emulator", "metacell_tools", "protocol", "tests", "docs"):
        for f in sorted((ROOT / base).rglob("*")):
            if f.suffix in (".py", ".md", ".toml", ".c", ".h") and f.is_file():
                for m in CODE_REF.finditer(f.read_text(errors="replace")):
                    yield f, m.group(1), m.group(2)
    for m in CODE_REF.finditer((ROOT / "README.md").read_text()):
        yield ROOT / "README.md", m.group(1), m.group(2)


def test_code_points_to_anchors_that_exist():
    bad = []
    cache: dict[str, set[str]] = {}
    for f, page, anchor in code_refs():
        dest = ROOT / "docs" / page
        if not dest.exists():
            bad.append(f"{f.relative_to(ROOT)}: docs/{page} does not exist")
            continue
        if anchor.startswith("<"):
            continue
        have = cache.setdefault(page, anchors(dest))
        if anchor not in have:
            bad.append(f"{f.relative_to(ROOT)}: docs/{page}#{anchor}")
    assert not bad, "\n".join(bad)
