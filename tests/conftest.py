import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(scope="module")
def server():
    """A Hops server on a free port for the tests of one module."""
    from shellform.hops import start

    srv, thread = start(port=0)
    yield srv
    srv.shutdown()
    srv.server_close()
    thread.join(5)
