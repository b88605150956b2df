"""The GIL is released during heavy calls, and concurrent calls give the same results."""
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import mvkp


def ticks_during(fn):
    """How far another Python thread gets while fn() runs (about 0 if fn holds the GIL)."""
    count = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            count[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    try:
        before = count[0]
        fn()
        return count[0] - before
    finally:
        stop.set()
        t.join()


def test_gil_released_in_train_and_match(target, model):
    assert ticks_during(lambda: mvkp.train(target, views=30, locations=80)) > 1000
    frames = [mvkp.make_scene_view(target, s)[0] for s in range(3)]
    m = mvkp.Matcher(model)
    assert ticks_during(lambda: [m.match(f) for f in frames for _ in range(5)]) > 1000


def test_concurrent_matches_agree(model, target):
    frames = [mvkp.make_scene_view(target, s)[0] for s in range(1, 7)]
    m = mvkp.Matcher(model)
    serial = [m.match(f).homography for f in frames]
    with ThreadPoolExecutor(4) as ex:
        parallel = list(ex.map(lambda f: m.match(f).homography, frames * 2))
    for a, b in zip(serial * 2, parallel):
        np.testing.assert_array_equal(a, b)


def test_concurrent_recognize_and_add(model, target):
    from conftest import SAMPLES

    others = [mvkp.train(mvkp.prepare_target(mvkp.load_image(str(SAMPLES / f"{n}.jpg")), 240), views=30)
              for n in ("baboon", "fruits", "coffee")]
    rec = mvkp.Recognizer()
    rec.add("a", model)
    frame = mvkp.make_scene_view(target, 2)[0]

    def work(i):
        if i % 4 == 3:  # adds wait for running recognitions, recognitions for adds
            rec.add(f"b{i}", others[i // 4])
            return None
        return rec.recognize(frame).ids

    with ThreadPoolExecutor(4) as ex:
        out = list(ex.map(work, range(12)))
    assert all(r is None or r == ["a"] for r in out), out
    assert len(rec) == 1 + 3
