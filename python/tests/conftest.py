"""Fixtures shared by the Python tests."""
import pytest


@pytest.fixture(scope="module")
def client():
    """A Dask client on a local cluster of two one-thread worker processes (loopback only), one per test
    module, closed after it."""
    from distributed import Client, LocalCluster
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None)
    c = Client(cluster)
    c.wait_for_workers(2, timeout=120)
    yield c
    c.close()
    cluster.close()
