import dynabarn


def test_star_import_exposes_everything_in_all():
    namespace: dict = {}
    exec("from dynabarn import *", namespace)
    missing = [name for name in dynabarn.__all__ if name not in namespace]
    assert not missing


def test_importing_the_package_changes_no_global_state():
    # Names load on first use: `import dynabarn` neither imports MuJoCo nor sets MUJOCO_GL.
    import subprocess
    import sys

    code = (
        "import os, sys; os.environ.pop('MUJOCO_GL', None); import dynabarn, dynabarn.cli;"
        "print('mujoco' in sys.modules, 'MUJOCO_GL' in os.environ, dynabarn.WorldSpec.__name__)"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.split() == ["False", "False", "WorldSpec"]


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
