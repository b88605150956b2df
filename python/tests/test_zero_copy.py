"""Zero-copy where the module promises it."""
import tracemalloc

import numpy as np

import mvkp


def test_model_descriptors_are_views(model):
    a, b = model.descriptors, model.descriptors
    assert a.ctypes.data == b.ctypes.data  # the same C++ buffer, not two copies
    assert np.shares_memory(a, b)
    assert not a.flags.owndata and not a.flags.writeable
    assert a.base is model  # keeps the model alive
    la, lb = model.labels, model.labels
    assert la.ctypes.data == lb.ctypes.data and la.dtype == np.int32 and not la.flags.writeable


def test_view_outlives_python_reference(target):
    m = mvkp.train(target, views=20, locations=60)
    d = m.descriptors
    expected = d.copy()
    del m  # the view holds the model
    np.testing.assert_array_equal(d, expected)


def test_cdikp_descriptors_own_cxx_buffer(target):
    _, desc = mvkp.Cdikp().detect_and_compute(target)
    assert not desc.flags.owndata and desc.base is not None  # a capsule over the cv::Mat
    assert type(desc.base).__name__ == "PyCapsule"


def _peak_during(fn):
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_ffva_build_reads_float32_in_place():
    rng = np.random.default_rng(0)
    data = rng.normal(size=(50_000, 32)).astype(np.float32)  # 6.4 MB
    # numpy reports its buffer allocations to tracemalloc: a conversion copy would show.
    peak32 = _peak_during(lambda: mvkp.FfvaIndex(data))
    assert peak32 < data.nbytes / 20, peak32
    data64 = data.astype(np.float64)
    peak64 = _peak_during(lambda: mvkp.FfvaIndex(data64))
    assert peak64 >= data.nbytes  # float64 is converted (one float32 copy): the check can see copies


def test_image_input_is_not_copied(model, target):
    frame, _ = mvkp.make_scene_view(target, 1)
    big = np.ascontiguousarray(np.tile(frame, (2, 2)))  # 1.2 MB
    peak = _peak_during(lambda: mvkp.Matcher(model).match(big))
    assert peak < big.nbytes / 4, peak
    # a column crop keeps rows contiguous: also read in place
    crop = big[:, 100:900]
    peak = _peak_during(lambda: mvkp.Matcher(model).match(crop))
    assert peak < crop.nbytes / 4, peak


def test_city_rasters_are_views():
    if not mvkp.HAS_AERIAL:
        return
    c = mvkp.make_city(3, width=200, height=200, buildings=4, trees=5, photo_max_side=300)
    assert c.depth.ctypes.data == c.depth.ctypes.data and not c.depth.flags.owndata
    assert c.depth.dtype == np.float32 and c.photo.shape[2] == 3
