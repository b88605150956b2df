"""FFVA exact kNN against numpy brute force."""
import numpy as np
import pytest

import mvkp


def brute(data, queries, k):
    d = ((queries[:, None, :].astype(np.float64) - data[None, :, :]) ** 2).sum(-1)
    ids = np.argsort(d, axis=1, kind="stable")[:, :k]
    return np.take_along_axis(d, ids, 1), ids


@pytest.mark.parametrize("n,dim,k", [(3000, 20, 5), (1000, 64, 10), (70, 8, 3)])
def test_ffva_equals_brute_force(n, dim, k):
    rng = np.random.default_rng(n + dim)
    data = rng.normal(size=(n, dim)).astype(np.float32)
    queries = rng.normal(size=(200, dim)).astype(np.float32)
    index = mvkp.FfvaIndex(data)
    assert index.size == n and index.dim == dim and len(index) == n
    dist, ids = index.search(queries, k)
    bd, bids = brute(data, queries, k)
    assert ids.dtype == np.int32 and dist.dtype == np.float32 and ids.shape == (200, k)
    np.testing.assert_array_equal(ids, bids)
    np.testing.assert_allclose(dist, bd, rtol=1e-4, atol=1e-4)
    # the brute-force index agrees too
    d2, i2 = mvkp.BruteForceIndex(data).search(queries, k)
    np.testing.assert_array_equal(i2, bids)


def test_two_distinct_labels():
    rng = np.random.default_rng(7)
    data = rng.normal(size=(500, 20)).astype(np.float32)
    labels = np.repeat(np.arange(100), 5).astype(np.int32)
    q = rng.normal(size=(50, 20)).astype(np.float32)
    dist, ids, labs = mvkp.FfvaIndex(data, labels).search_two_distinct(q)
    d = ((q[:, None, :].astype(np.float64) - data[None]) ** 2).sum(-1)
    first = d.argmin(1)
    np.testing.assert_array_equal(ids[:, 0], first)
    masked = np.where(labels[None, :] == labels[first][:, None], np.inf, d)
    np.testing.assert_array_equal(ids[:, 1], masked.argmin(1))
    assert (labs[:, 0] != labs[:, 1]).all()


def test_save_load(tmp_path):
    rng = np.random.default_rng(3)
    data = rng.normal(size=(400, 16)).astype(np.float32)
    q = rng.normal(size=(20, 16)).astype(np.float32)
    idx = mvkp.FfvaIndex(data, leaf_size=32)
    p = str(tmp_path / "x.ffva")
    idx.save(p)
    loaded = mvkp.load_index(p, mmap=True)
    np.testing.assert_array_equal(loaded.search(q, 4)[1], idx.search(q, 4)[1])
    with open(p, "r+b") as f:
        f.seek(-4000, 2)  # inside the vectors section, covered by the CRC
        f.write(b"\xff" * 64)
    with pytest.raises(mvkp.BadIndexError):
        mvkp.load_index(p)


def test_index_input_errors():
    with pytest.raises(TypeError, match="None"):
        mvkp.FfvaIndex(None)
    with pytest.raises(ValueError, match="2-D"):
        mvkp.FfvaIndex(np.zeros(10, np.float32))
    idx = mvkp.FfvaIndex(np.zeros((40, 4), np.float32) + np.arange(4, dtype=np.float32))
    with pytest.raises(ValueError, match="4 columns"):
        idx.search(np.zeros((2, 5), np.float32))
    with pytest.raises(ValueError, match="labels"):
        mvkp.FfvaIndex(np.zeros((4, 4), np.float32), labels=np.zeros(3, np.int32))
    with pytest.raises(mvkp.InvalidArgumentError):
        mvkp.FfvaIndex(np.full((40, 4), np.nan, np.float32))
