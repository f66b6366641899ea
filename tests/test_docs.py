"""The docs and the code's comments speak of the toolkit as it is (issue 38).

Two checks over ``README.md``, ``docs/*.md`` and the comments and docstrings of
``toolkit/``, ``recipes/`` and ``benchmarks/``:

* no work diary: no numbered sittings of the work (the word for a sitting
  followed by its number, alone or in a range), none called "this" or "the
  previous" one, and no names of the people or assistants who did the work
  (a figure keeps its command, scenes and date; git keeps who and when).  The
  word "session" in its other senses (a Pose2Sim session folder, the
  correction app's session, a keypoint session, pytest's session fixtures) is
  not matched by the patterns or is allowed below;
* no dead relative link or image in the Markdown docs: ``[text](path)`` and
  ``![alt](path)`` (not http(s), mailto or ``#anchor``) must name an existing
  file or folder, resolved from the doc's own folder, ``#anchor`` stripped.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CODE_DIRS = ("toolkit", "recipes", "benchmarks")

#: The word for one sitting of the work, which a diary numbers.
PERIOD = "session"

DIARY = [
    re.compile(rf"\b{PERIOD}s?[-\s]+\d+", re.IGNORECASE),                  # the word, then a number
    re.compile(rf"\b(this|previous|last|next|another) {PERIOD}\b", re.IGNORECASE),
    re.compile(r"\bthe lead\b|\blead's\b|\(lead\)|,\s*lead\)|\bhelpers?\s+[a-z]+\d*\b(?=[,.;:)]|\s+(did|wrote|"
               r"found|measured|ran))", re.IGNORECASE),
]

#: Lines holding one of these use "session" in another sense.
ALLOWED = re.compile(r"keypoint session|correction session|test session|rerun session|terminal session|"
                     r"pose2sim|S\d\d_", re.IGNORECASE)


def _docs() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _code_files() -> list[Path]:
    return [p for d in CODE_DIRS for p in sorted((ROOT / d).rglob("*.py"))]


def _comments_and_docstrings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every comment and docstring line of a Python file."""
    src = path.read_text(encoding="utf-8")
    lines = src.splitlines()
    out = []
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.COMMENT:
            out.append((tok.start[0], tok.string))
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                start, end = first.value.lineno, first.value.end_lineno
                out += [(no, lines[no - 1]) for no in range(start, end + 1)]
    return out


def _diary_hits(lines) -> list[tuple[int, str]]:
    hits = []
    for no, line in lines:
        if ALLOWED.search(line):
            continue
        for pat in DIARY:
            m = pat.search(line)
            if m:
                hits.append((no, m.group(0)))
                break
    return hits


def test_docs_and_comments_hold_no_work_diary():
    found = []
    for doc in _docs():
        lines = enumerate(doc.read_text(encoding="utf-8").splitlines(), start=1)
        found += [f"{doc.relative_to(ROOT)}:{no}: {hit!r}" for no, hit in _diary_hits(lines)]
    for f in _code_files():
        if not any(pat.search(f.read_text(encoding="utf-8")) for pat in DIARY):
            continue  # nothing to look at more closely: skip tokenizing it (keeps the test fast)
        found += [f"{f.relative_to(ROOT)}:{no}: {hit!r}" for no, hit in _diary_hits(_comments_and_docstrings(f))]
    assert not found, "work diary in docs or comments (state the fact, not who did it or when):\n" + "\n".join(found)


LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^(```|~~~).*?^\1", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"`[^`\n]*`")


def _dead_links(doc: Path) -> list[str]:
    text = doc.read_text(encoding="utf-8")
    # blank out code blocks and spans, keeping the line numbers
    text = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    dead = []
    for no, line in enumerate(text.splitlines(), start=1):
        for m in LINK.finditer(CODE_SPAN.sub("", line)):
            target = m.group(1)
            if re.match(r"[a-z][a-z0-9+.-]*:|#", target, re.IGNORECASE):  # http(s):, mailto:, #anchor
                continue
            path = target.split("#", 1)[0].split("?", 1)[0]
            if path and not (doc.parent / path).exists():
                dead.append(f"{doc.relative_to(ROOT)}:{no}: {target}")
    return dead


def test_relative_links_and_images_in_the_docs_exist():
    dead = [d for doc in _docs() for d in _dead_links(doc)]
    assert not dead, "links to files that do not exist:\n" + "\n".join(dead)


def test_the_checks_see_what_they_should():
    # the patterns catch the diary forms and leave the other senses of "session" alone
    numbered, hyphened = f"{PERIOD} 12", f"{PERIOD}-7"
    lead = "the " + "lead"
    assert _diary_hits([(1, f"Measured in {numbered} (fresh seeds)"), (2, f"the {hyphened} change"),
                        (3, f"# run by {lead}"), (4, "helper abc measured it")]) == [
        (1, numbered), (2, hyphened), (3, lead), (4, "helper abc")]
    assert _diary_hits([(1, "a Pose2Sim session folder, Session/S00_Calibration"), (2, "one correction session"),
                        (3, "python /tmp/scratch/loop.py"), (4, "the session's Calib*.toml"),
                        (5, "@pytest.fixture(scope=\"session\")")]) == []


# ----------------------------------------------------------------- README, user guides, anchors, recipe flags

#: The user guides, one per input kind, that README.md links to.
GUIDES = ("guide_videos.md", "guide_depth.md", "guide_markers.md", "guide_point_clouds.md")
HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*#*\s*$", re.MULTILINE)
RECIPE_CALL = re.compile(r"recipes/([a-z][a-z0-9_]*)\.py\b")   # NAME.py: a placeholder
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _recipes() -> list[str]:
    return sorted(p.stem for p in (ROOT / "recipes").glob("*.py") if p.stem != "__init__")


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.replace("`", "").strip().lower()).replace(" ", "-")


def _anchors(doc: Path) -> set[str]:
    text = FENCE.sub("", doc.read_text(encoding="utf-8"))
    return {_slug(h) for h in HEADING.findall(text)}


def _commands(doc: Path) -> list[str]:
    """Every shell command of a doc's code blocks (continuation lines joined) and code spans."""
    text = doc.read_text(encoding="utf-8")
    out = []
    for block in FENCE.finditer(text):
        out += block.group(0).replace("\\\n", " ").splitlines()[1:-1]
    out += [span.strip("`") for span in CODE_SPAN.findall(FENCE.sub("", text))]
    return out


def _recipe_calls(command: str) -> list[tuple[str, list[str]]]:
    """(recipe, flags given to it) for each ``recipes/NAME.py`` call of one command line."""
    command = re.split(r"\s#", command)[0]                       # a trailing shell comment
    calls = []
    for part in re.split(r"&&|;|\|(?!\w)", command):
        for m, nxt in zip(RECIPE_CALL.finditer(part), [*list(RECIPE_CALL.finditer(part))[1:], None]):
            args = part[m.end():nxt.start() if nxt else None]
            calls.append((m.group(1), FLAG.findall(args)))
    return calls


def test_readme_names_every_recipe_and_links_every_guide():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    missing = [r for r in _recipes() if f"{r}.py" not in readme]
    assert not missing, f"recipes the README does not name: {missing}"
    for guide in GUIDES:
        assert (ROOT / "docs" / guide).is_file(), f"docs/{guide} is missing"
        assert f"(docs/{guide})" in readme, f"README.md does not link docs/{guide}"
    for cmd in ("bash scripts/run_default.sh", "bash scripts/test.sh"):
        assert f"\n    {cmd}\n" in readme, f"README.md lost its set-up command {cmd!r}"


def test_each_guide_shows_pictures_and_its_recipes():
    for guide, recipe in zip(GUIDES, ("free_viewpoint", "depth_tracking", "joint_centres", "fit_soft_body")):
        text = (ROOT / "docs" / guide).read_text(encoding="utf-8")
        assert re.search(r"!\[[^\]]*\]\(images/", text), f"docs/{guide} shows no picture"
        assert f"recipes/{recipe}.py" in text, f"docs/{guide} never runs recipes/{recipe}.py"


def test_anchors_of_links_between_the_docs_exist():
    bad = []
    for doc in _docs():
        text = CODE_SPAN.sub("", FENCE.sub("", doc.read_text(encoding="utf-8")))
        for m in LINK.finditer(text):
            target = m.group(1)
            if "#" not in target or re.match(r"[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
                continue
            path, anchor = target.split("#", 1)
            linked = (doc.parent / path) if path else doc
            if linked.suffix == ".md" and linked.is_file() and anchor not in _anchors(linked):
                bad.append(f"{doc.relative_to(ROOT)}: {target}")
    assert not bad, "links to headings that do not exist:\n" + "\n".join(bad)


def test_recipe_commands_in_readme_and_guides_use_existing_recipes_and_flags():
    recipes = set(_recipes())
    bad = []
    for doc in [ROOT / "README.md", *(ROOT / "docs" / g for g in GUIDES)]:
        for command in _commands(doc):
            for recipe, flags in _recipe_calls(command):
                if recipe not in recipes:
                    bad.append(f"{doc.name}: recipes/{recipe}.py does not exist")
                    continue
                source = (ROOT / "recipes" / f"{recipe}.py").read_text(encoding="utf-8")
                bad += [f"{doc.name}: recipes/{recipe}.py has no option {flag}" for flag in flags
                        if flag != "--help" and f'"{flag}"' not in source and f"'{flag}'" not in source]
    assert not bad, "\n".join(bad)


def test_the_recipe_and_anchor_checks_see_what_they_should():
    assert _slug("Soft-body models from point clouds") == "soft-body-models-from-point-clouds"
    assert _slug("Calibration from scratch (board, people)") == "calibration-from-scratch-board-people"
    assert _recipe_calls(".venv/bin/python recipes/free_viewpoint.py T --out O --max-frames 4  # not --this") == [
        ("free_viewpoint", ["--out", "--max-frames"])]
    assert _recipe_calls("recipes/make_scene.py S --out D && recipes/depth_tracking.py D --out E --frames 3") == [
        ("make_scene", ["--out"]), ("depth_tracking", ["--out", "--frames"])]


def test_every_picture_in_docs_is_shown_or_made_somewhere():
    """A picture in ``docs/images`` that no document shows and no benchmark writes is left behind by an
    earlier figure: remove it (git keeps it)."""
    texts = [p.read_text(encoding="utf-8") for p in _docs()] + [p.read_text(encoding="utf-8")
                                                                 for p in _code_files()]
    orphans = [p.name for p in sorted((ROOT / "docs" / "images").iterdir())
               if p.is_file() and not any(p.name in t for t in texts)]
    assert not orphans, f"pictures nobody shows: {orphans}"
