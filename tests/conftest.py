from __future__ import annotations

import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
REFERENCE = REPO.parent / "shared" / "reference"


@pytest.fixture(scope="session")
def release_json() -> dict:
    path = REFERENCE / "dynabarn60.json"
    if not path.is_file():
        pytest.skip("reference data ../shared/reference/dynabarn60.json not present")
    return json.loads(path.read_text())


@pytest.fixture(scope="session")
def release_path(release_json) -> Path:
    return REFERENCE / "dynabarn60.json"
