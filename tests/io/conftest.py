"""Fixtures of the RAW reading tests."""

from __future__ import annotations

import pytest

ARW_NAME = "sony-ilce7rm3-DSC2164.ARW"  # the real Sony A7R III ARW in ../shared/data/raw


@pytest.fixture
def arw(shared_data):
    """The real ARW's path; the test is skipped when ../shared/data is absent."""
    path = shared_data / "raw" / ARW_NAME
    if not path.is_file():
        pytest.skip(f"{path} not found")
    return path
