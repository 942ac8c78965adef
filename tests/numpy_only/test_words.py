"""Words a newcomer understands, held in every tracked text file:

- no process words: a reader who was not there cannot tell what "issue 26's bar", "the fourth
  session" or "turn 3" was; say what the bar is or what changed, and when (a date);
- every equation reference names its paper: several sources number their equations (Yusov 2013
  and 2012, Hoffman & Preetham 2002, Bruneton 2017), so a bare "eq. (8)" or "Listing 2" is a guess;
- README's Documentation section links every page of docs/.

CHANGELOG.md may speak of dates and past work freely and is not checked; nor is this file, whose
matcher tests spell out what is refused."""
import os
import re
import subprocess

import pytest

from extension import ROOT

SUFFIXES = {".py", ".md", ".sh", ".toml", ".txt", ".json"}
NOT_CHECKED = {"CHANGELOG.md", "tests/numpy_only/test_words.py"}
NOT_WALKED = {".git", ".venv", "build", "dist", "luts", "__pycache__", ".pytest_cache"}

# Being split or rewritten on other branches while these words were fixed; their hits are fixed
# there. Empty this set once those branches are merged.
PENDING = {
    "addon/nodes/light_shafts.py",       # being split on another branch
    "sample_blend/build_sample.py",
    "docs/design.md",
}

_ORDINALS = (r"first|second|third|fourth|fifth|sixth|seventh|eighth|ninth|tenth|eleventh|twelfth"
             r"|\d+(?:st|nd|rd|th)")
# "turn 90 deg" is a rotation and "stop 2 km out" a distance.
_NOT_A_QUANTITY = r"(?!\.\d|\s*(?:deg\b|°|degrees?\b|rad\b|%|x\b|k?m\b|mm\b|m?s\b|px\b|pixels?\b|EV\b))"
PROCESS_WORDS = re.compile(rf"""
      (?<![a-z])issues?[\s_]*\#?\d+                 # issue 25, issues #3, ISSUE_27_BASELINE
    | \b(?:{_ORDINALS})[\s-]+session\b              # the fourth session
    | (?<![a-z])session[\s_]*\#?\d+\b{_NOT_A_QUANTITY}  # session 4
    | (?<![a-z])turn[\s_]*\d+\b{_NOT_A_QUANTITY}    # turn 3
    | (?<![a-z-])stop[\s_]*\d+\b{_NOT_A_QUANTITY}   # stop 2 (not an f-stop)
""", re.I | re.X)

# "eq. (8)", "Eq. 5", "eqs. (4)-(7)", "equations 1 and 2", "Listing 2", "Listings 1-2": the whole
# reference, so that "eqs. (4)-(7) of Yusov 2013" is seen to name its paper after it.
_NUMBER = r"\(?\d+[a-z]?\)?"
_MORE = rf"(?:\s*(?:-|–|,|and|to)\s*{_NUMBER})*"
EQUATION_REFERENCE = re.compile(rf"\b(?:eqs?\.|equations?)\s*{_NUMBER}{_MORE}|\blistings?\s+\d+{_MORE}", re.I)
PAPER = re.compile(r"Yusov,?\s*(?:et al\.?\s*)?\(?(?:2012|2013)|Hoffman\s*(?:&|and|-)\s*Preetham|Preetham"
                   r"|Bruneton|Hillaire|Nishita|Kasten|Elek", re.I)
PAPER_BEFORE_CHARS = 40
# Only "of": "eq. (8) in Bruneton's code" says where it is coded, not whose equation it is.
PAPER_AFTER = re.compile(rf"\s+of\s+(?:{PAPER.pattern})", re.I)


def process_words(line):
    """The process words on ``line``, as written."""
    return [m.group(0) for m in PROCESS_WORDS.finditer(line)]


def unnamed_equations(line):
    """The equation and listing references on ``line`` with no paper named within
    PAPER_BEFORE_CHARS before them, nor right after them ("eq. (8) of Yusov 2013")."""
    unnamed = []
    for m in EQUATION_REFERENCE.finditer(line):
        before = line[max(0, m.start() - PAPER_BEFORE_CHARS):m.start()]
        if not PAPER.search(before) and not PAPER_AFTER.match(line, m.end()):
            unnamed.append(m.group(0))
    return unnamed


def text_files():
    """Repository-relative paths of the tracked text files that are checked."""
    try:
        listed = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True)
        paths = listed.stdout.splitlines()
    except (OSError, subprocess.CalledProcessError):      # no git, or not a checkout: walk the tree
        paths = []
        for folder, subfolders, files in os.walk(ROOT):
            subfolders[:] = [s for s in subfolders if s not in NOT_WALKED and not s.startswith(".")]
            paths.extend(os.path.relpath(os.path.join(folder, f), ROOT).replace(os.sep, "/") for f in files)
    return sorted(p for p in paths if os.path.splitext(p)[1] in SUFFIXES and p not in NOT_CHECKED
                  and (ROOT / p).is_file())


def hits(finder, skip=PENDING):
    found = []
    for path in text_files():
        if path in skip:
            continue
        for number, line in enumerate((ROOT / path).read_text(errors="replace").splitlines(), 1):
            found.extend(f"{path}:{number}: {word!r}" for word in finder(line))
    return found


def test_no_process_words():
    found = hits(process_words)
    assert not found, ("say what changed and why instead (a date, the bar itself):\n" + "\n".join(found))


def test_every_equation_reference_names_its_paper():
    found = hits(unnamed_equations)
    assert not found, ("name the paper, e.g. 'Yusov 2013 eq. (8)', 'Hoffman & Preetham Eq. 5':\n"
                       + "\n".join(found))


def test_the_file_list_finds_this_repository():
    paths = text_files()
    assert "README.md" in paths and "lut_gen/tables/parameterization.py" in paths
    assert not NOT_CHECKED & set(paths)


@pytest.mark.parametrize("line", [
    "Single scattering at a low sun (issue 26): the tables against",
    "the baker before ISSUE_27_BASELINE",
    "see issues #12 and 13",
    "Issue 27's bar at 16 steps",
    "As until the fourth session, four orders",
    "(tenth session; bench/bench_frame_numpy.py)",
    "measured in session 3",
    "fixed in turn 3",
    "left for stop 2",
])
def test_process_words_are_caught(line):
    assert process_words(line), line


@pytest.mark.parametrize("line", [
    "the first time in a session of a Blender process",
    "the first time in a session 0.9-1.0 s, later 0.5 s",
    '@pytest.fixture(scope="session")',
    "interactive sessions only; scripts call the operator themselves",
    "a known issue of OpenEXR: https://github.com/AcademySoftwareFoundation/openexr/issues/1234",
    "the issue of banding at the horizon",
    "rotate the sun a quarter turn 90 deg to the west",
    "the lens at f-stop 2.8, or one stop 2 EV down; the rays stop 2 km out",
    "def tissue_2(x): return x",
])
def test_ordinary_prose_passes_the_process_words(line):
    assert not process_words(line), process_words(line)


@pytest.mark.parametrize("line", [
    "the blend of eq. (8) along the ray",
    "x_a of eq. (5) with the horizon flag",
    "Eqs. (4)-(7) and their inverses",
    "# -- height (eq. 4) ---",
    "Eq. 5 has no twilight",
    "the horizon split (Listing 2) keeps x_a inside one half",
    "Yusov 2013 eq. (8) and, far further along this same line of text, eq. (5)",
    "Yusov's eq. (8)",
    "eq. (8) in Bruneton's code",
])
def test_unnamed_equations_are_caught(line):
    assert unnamed_equations(line), line


@pytest.mark.parametrize("line", [
    "Yusov 2013 eq. (8) over a ray section",
    "Eq. (8) of Yusov 2013 in a compositor tree",
    "Eqs. (4)-(7) of Yusov 2013 and Listing 2: texel mappings",
    "Yusov 2013 eqs. (4) and (5)",
    "Listing 1 of Yusov 2013 over our 2D atlas",
    "the twilight of Hoffman & Preetham Eq. 5 is absent",
    "(Hoffman-Preetham Eqs. 3 and 4)",
    "Bruneton 2017 eq. (6)",
    "Yusov 2012 eq. (3): the epipolar lines",
    "the equation of state and a listing of files",
    "a freq. 5 Hz hum, req. 3 of the manifest",
])
def test_named_equations_pass(line):
    assert not unnamed_equations(line), unnamed_equations(line)


def documentation_section(readme):
    """README's "## Documentation" section, up to the next heading of its level or higher."""
    match = re.search(r"^## Documentation\n(.*?)(?=^#{1,2} |\Z)", readme, re.S | re.M)
    assert match, "README.md has no '## Documentation' section"
    return match.group(1)


def test_readme_links_every_docs_page():
    section = documentation_section((ROOT / "README.md").read_text())
    linked = set(re.findall(r"\]\((docs/[^)#\s]+\.md)", section))
    pages = {f"docs/{p.name}" for p in (ROOT / "docs").glob("*.md")}
    assert pages <= linked, f"README.md's Documentation section lacks {sorted(pages - linked)}"
    assert linked <= pages, f"README.md's Documentation section links missing pages {sorted(linked - pages)}"
