"""The layout rules of docs/architecture.md, checked on the source (issue 8): no import cycles,
no private names imported across modules, no module over the size cap, and packages that only
depend on earlier pipeline stages."""

from __future__ import annotations

from import_graph import PIPELINE, REPO, import_graph

MAX_MODULE_LINES = 420


def test_no_import_cycles_between_modules():
    assert import_graph().cycles() == []


def test_no_private_names_imported_across_modules():
    assert import_graph().private == []


def test_every_module_is_within_the_size_cap():
    big = {m: n for m, p in import_graph().modules.items() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert big == {}, f"modules over {MAX_MODULE_LINES} lines: {big}"


def test_packages_depend_only_on_earlier_stages():
    """An arrow from a package to a later pipeline stage is a layering error (the scene package
    may read the capture's effect registry to check a scene's effect names: declared here)."""
    allowed_back = {("scene", "capture")}
    order = {p: i for i, p in enumerate(PIPELINE)}
    back = sorted((a, b) for a, b in import_graph().package_edges()
                  if a in order and b in order and order[b] > order[a] and (a, b) not in allowed_back)
    assert back == []


def test_the_graph_sees_a_planted_cycle_and_private_import(tmp_path):
    """The checker itself can fail: a two-module cycle and a private import are found."""
    pkg = tmp_path / "envcap"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from envcap.b import _hidden\n")
    (pkg / "b.py").write_text("def f():\n    from envcap import a\n_hidden = 1\n")
    g = import_graph(tmp_path)
    assert g.cycles() == [["envcap.a", "envcap.b"]]
    assert g.private == [("envcap.a", "envcap.b", "_hidden")]
    assert g.inner == [("envcap.b", 2)]


def test_repo_root_is_the_checkout():
    assert (REPO / "envcap" / "__init__.py").is_file()


def test_every_module_is_named_in_the_architecture_page():
    """docs/architecture.md names every package (``core/``) and every module (by its file name,
    in backquotes), so the page cannot silently drift from the tree again."""
    page = (REPO / "docs" / "architecture.md").read_text()
    missing = []
    for name, path in import_graph().modules.items():
        parts = name.split(".")
        if len(parts) < 2 or parts[-1] in ("__init__", "__main__"):
            continue
        if path.name == "__init__.py":
            token = f"`{parts[-1]}/`"
        else:
            token = f"`{parts[-1]}`"
        if token not in page and f"`{'/'.join(parts[1:])}" not in page and f"{parts[-1]}.py" not in page:
            missing.append(name)
    assert missing == []
