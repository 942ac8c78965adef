"""Every command the README and docs/*.md show runs as written, at small sizes: the shell blocks
are read from the pages themselves, so a change that breaks one fails here.

Each command runs in a scratch folder that links the repository's files, so what it writes
(build/, luts/, dist/, out.png) lands there. Sizes are made small by appending options the
command already takes (argparse keeps the last): --resolution draft for bakes and previews,
--resolution 32x18 --samples 1 --tables draft for renders."""
import ast
import os
import re
import shutil
import subprocess

import pytest
from extension import ROOT

README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
API_PAGE = ROOT / "docs" / "lut_gen.md"      # the Python API block
SMALL_RENDER = " --resolution 32x18 --samples 1 --tables draft"


def shell_commands(pages=PAGES):
    """("page:line", command) for every command line of the pages' sh blocks; a block that sets
    a variable runs whole."""
    commands = []
    for page in pages:
        commands.extend((f"{page.relative_to(ROOT)}:{line}", command) for line, command in _page_commands(page))
    return commands


def _page_commands(page):
    text = page.read_text()
    commands = []
    for block in re.finditer(r"\s*```(?:sh|bash)\n(.*?)```", text, re.S):
        first_line = text[:block.start()].count("\n") + 2
        body = block.group(1).replace("\\\n", " ")
        lines = [re.sub(r"\s+#.*$", "", line).strip() for line in body.splitlines()]
        lines = [line for line in lines if line and not line.startswith("#")]
        if any(re.match(r"^[A-Z_]+=", line) for line in lines):
            commands.append((first_line, " && ".join(lines)))
        else:
            commands.extend((first_line, line) for line in lines)
    return commands


def why_skipped(command):
    if command.startswith("scripts/test.sh"):
        return "the test suite itself (CI runs it)"
    if command.startswith("blender ") and shutil.which("blender") is None:
        return "no Blender binary on this machine (the bpy module runs the same script)"
    if "LUT_DIR" in command or "[--" in command:
        return "a template with placeholders, not a command"
    return None


def small(command):
    if "scripts/render.py" in command or command.startswith("scripts/run_sample.sh"):
        return command + SMALL_RENDER
    if re.search(r"-m lut_gen (bake|sample)\b", command) and "--help" not in command:
        return command + " --resolution draft"
    return command


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A folder that looks like the repository (links to its files) to run commands in."""
    folder = tmp_path_factory.mktemp("readme")
    for entry in ROOT.iterdir():
        if entry.name in {"build", "dist", ".git", ".pytest_cache", "__pycache__"}:
            continue
        (folder / entry.name).symlink_to(entry)
    return folder


def test_readme_has_the_two_main_commands():
    commands = [c for _, c in shell_commands([README])]
    assert "scripts/run_sample.sh" in commands and "scripts/test.sh" in commands
    assert "scripts/build_extension.sh" in commands and any("blender_ext.py build" in c for c in commands)


def test_readme_is_short_and_links_resolve():
    assert len(README.read_bytes()) <= 12_000
    for page in PAGES + [ROOT / "CHANGELOG.md"]:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target:
                assert (page.parent / target).exists(), f"{page.relative_to(ROOT)} links to missing {target}"


@pytest.mark.parametrize("line, command", shell_commands(), ids=lambda v: str(v)[:60])
def test_readme_command_runs(line, command, scratch, tmp_path):
    reason = why_skipped(command)
    if reason:
        pytest.skip(f"{line}: {reason}")
    builds = "blender_ext.py build" in command or command.startswith("scripts/build_extension.sh")
    if builds:
        # The extension build reads its source folder: a real copy, not links.
        source = tmp_path / "source"
        shutil.copytree(ROOT, source, symlinks=True, ignore=shutil.ignore_patterns(
            ".venv", ".git", "build", "dist", "__pycache__", ".pytest_cache", "cache"))
        (source / ".venv").symlink_to(ROOT / ".venv")
        cwd = source
    else:
        cwd = scratch
    env = dict(os.environ, OLS_CACHE_DIR=str(scratch / "cache"))
    env.pop("PYTHONPATH", None)
    result = subprocess.run(["bash", "-c", small(command)], cwd=cwd, env=env, capture_output=True,
                            text=True, timeout=900)
    assert result.returncode == 0, f"{line}: {command}\n{result.stdout[-1500:]}\n{result.stderr[-1500:]}"
    if "--output " in command:
        output = command.split("--output ")[1].split()[0]
        assert (cwd / output).exists(), f"{line} wrote no {output}"
    if builds:
        assert list((cwd / "dist").glob("*.zip")), "the extension build wrote no zip"


def test_python_api_names_exist():
    """The Python API block's names resolve (``reference`` and ``monte_carlo`` as imported there
    from lut_gen.verify, which ``import lut_gen`` does not load)."""
    import lut_gen
    from lut_gen.verify import monte_carlo, reference
    text = API_PAGE.read_text()
    block = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    tree = ast.parse(block)
    roots = {"lut_gen": lut_gen, "luts": lut_gen.Luts, "reference": reference, "monte_carlo": monte_carlo}
    checked = 0
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            chain = []
            while isinstance(node, ast.Attribute):
                chain.append(node.attr)
                node = node.value
            if isinstance(node, ast.Name) and node.id in roots:
                target = roots[node.id]
                for name in reversed(chain):
                    assert hasattr(target, name), f"README: {node.id}.{'.'.join(reversed(chain))}"
                    target = getattr(target, name)
                checked += 1
    assert checked >= 10


def test_gallery_images_exist_and_are_small():
    text = README.read_text()
    for preset in ("noon", "golden-hour", "sunset", "blue-hour"):
        path = ROOT / "docs" / "gallery" / f"{preset}.png"
        assert f"docs/gallery/{preset}.png" in text and f"--preset {preset}" in text
        assert path.read_bytes().startswith(b"\x89PNG") and path.stat().st_size < 300_000, path
