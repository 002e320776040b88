import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(autouse=True, scope="session")
def _cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Keep test caches out of the user's home unless asked otherwise."""
    os.environ.setdefault("GRASP_CACHE", str(tmp_path_factory.mktemp("cache")))
