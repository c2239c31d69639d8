"""The documentation site's generated pages, written at build time by the mkdocs-gen-files
plugin (``mkdocs.yml`` runs this file on every ``mkdocs build`` / ``mkdocs serve``).

* ``api/<module>.md``: one API reference page per public module of the project's packages
  (`PACKAGES`), titled by the module's name and holding ``::: <module>`` for mkdocstrings;
  ``api/index.md`` lists them all. A module is public when no part of its dotted name starts
  with ``_`` (so ``__main__`` and ``envs._gl`` are out, packages are in through their
  ``__init__.py``). Nothing lists modules by hand: a new module gets its page at the next
  build.
* ``tutorials/*.ipynb``: the notebooks of ``notebooks/``, rendered by mkdocs-jupyter with the
  outputs they were committed with (``execute: false``).
* ``changelog.md``: the repository's ``CHANGELOG.md``.
* ``results/images/*``: the committed result plots the results pages show (`IMAGES`).

Nothing is written into the work tree: the files exist only in the build.
Run as a script (``python docs/gen_pages.py``) it prints the API modules it would document.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The top-level packages whose public modules get an API page, in the reference's order.
PACKAGES = ("physics_planning", "envs", "skills", "abstract_planners", "hier_agents")

#: Committed result images the results pages show: path under ``results/`` -> name under
#: ``docs``' ``results/images/``.
IMAGES = {
    "compare/mujoban/comparison.png": "comparison.png",
    "compare/boards/comparison.png": "comparison_boards.png",
    "looks_side_by_side.png": "looks_side_by_side.png",
    "board_looks.png": "board_looks.png",
}


def public_modules(root: Path = ROOT, packages=PACKAGES) -> list[str]:
    """Dotted names of every public module of ``packages`` under ``root``, packages before
    their modules, in path order. Only folders with an ``__init__.py`` are packages."""
    names = []
    for package in packages:
        base = root / package
        if not (base / "__init__.py").is_file():
            raise FileNotFoundError(f"{base} is not a package (no __init__.py)")
        for path in sorted(base.rglob("*.py")):
            rel = path.relative_to(root).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts.pop()
            if any(part.startswith("_") for part in parts):
                continue
            if not all(
                (root.joinpath(*rel.parts[:i]) / "__init__.py").is_file()
                for i in range(1, len(rel.parts))
            ):
                continue
            names.append(".".join(parts))
    return sorted(names, key=lambda name: (packages.index(name.split(".")[0]), name))


def _first_line(root: Path, module: str) -> str:
    """The first sentence-line of a module's docstring, read statically ('' when none)."""
    import ast

    path = root.joinpath(*module.split("."))
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    line = doc.strip().split("\n\n")[0].replace("\n", " ")
    return line if len(line) <= 160 else line[:157].rstrip() + "..."


def api_index(modules: list[str], root: Path = ROOT) -> str:
    """The API reference's landing page: every module, linked, with its docstring's start."""
    lines = [
        "# API reference",
        "",
        "Generated from the docstrings (Google style: Args, Returns, Raises) of every "
        "public module; the page of a module documents its public names.",
        "",
    ]
    for package in PACKAGES:
        lines += [f"## `{package}`", "", "| module | what it is |", "| --- | --- |"]
        for module in (m for m in modules if m.split(".")[0] == package):
            summary = _first_line(root, module).replace("|", "\\|")
            lines.append(f"| [`{module}`]({module}.md) | {summary} |")
        lines.append("")
    return "\n".join(lines)


def generate() -> None:
    """Writes the generated pages into the build (only under mkdocs-gen-files)."""
    import mkdocs_gen_files

    modules = public_modules()
    for module in modules:
        with mkdocs_gen_files.open(f"api/{module}.md", "w") as page:
            page.write(f"---\ntitle: {module}\n---\n\n::: {module}\n")
        path = Path(*module.split("."))
        source = path / "__init__.py" if (ROOT / path).is_dir() else path.with_suffix(".py")
        mkdocs_gen_files.set_edit_path(f"api/{module}.md", Path("..") / source)
    with mkdocs_gen_files.open("api/index.md", "w") as page:
        page.write(api_index(modules))
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        with mkdocs_gen_files.open(f"tutorials/{notebook.name}", "w") as page:
            page.write(notebook.read_text())
    with mkdocs_gen_files.open("changelog.md", "w") as page:
        page.write((ROOT / "CHANGELOG.md").read_text())
    for source, name in IMAGES.items():
        with mkdocs_gen_files.open(f"results/images/{name}", "wb") as image:
            image.write((ROOT / "results" / source).read_bytes())


if __name__ == "__main__":
    print("\n".join(public_modules()))
else:
    generate()
