import dynabarn


def test_star_import_exposes_everything_in_all():
    namespace: dict = {}
    exec("from dynabarn import *", namespace)
    missing = [name for name in dynabarn.__all__ if name not in namespace]
    assert not missing


def test_modules_import_only_earlier_stages():
    """Data flows one way: a module never imports a later stage."""
    import ast
    from pathlib import Path

    order = [
        "errors",
        "profiles",
        "trajectory",
        "static_field",
        "world",
        "schedule",
        "robot",
        "difficulty",
        "mjcf",
        "worldset",
        "release",
        "barn",
        "plot",
        "protocol",
        "metrics",
        "planners",
        "sim",
        "wire",
        "recording",
        "replay",
        "render",
        "demos",
        "teleop",
        "bench",
    ]
    root = Path(dynabarn.__file__).parent
    for i, name in enumerate(order):
        path = root / name / "__init__.py" if (root / name).is_dir() else root / f"{name}.py"
        tree = ast.parse(path.read_text())
        imported = {
            node.module.split(".")[1]
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("dynabarn.")
        }
        later = imported & set(order[i + 1 :])
        assert not later, f"{name} imports later stage(s) {later}"


def test_readme_python_examples_run(tmp_path, monkeypatch, capsys):
    """Every ```python block of the README runs as written."""
    import re
    from pathlib import Path

    readme = (Path(dynabarn.__file__).parent.parent / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {"__name__": "__readme__"})
    out = capsys.readouterr().out
    assert "my_world | dwa | barn | seed 0:" in out and (tmp_path / "my_world.xml").is_file()
