"""Generator: shapes, dtypes, determinism, indexing, batches, pickling, the GIL."""

from __future__ import annotations

import pickle
import threading
import time

import numpy as np
import pytest
import synthgen

ARRAYS = ("rgb", "depth", "instance_ids", "masks", "masks_visib", "cam_K")


def same(a: synthgen.Frame, b: synthgen.Frame) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ARRAYS) and all(
        oa["obj_id"] == ob["obj_id"]
        and np.array_equal(oa["R"], ob["R"])
        and np.array_equal(oa["t"], ob["t"])
        for oa, ob in zip(a.objects, b.objects)
    )


def test_shapes_and_dtypes(gen: synthgen.Generator) -> None:
    f = gen[0]
    assert isinstance(f, synthgen.Frame)
    assert f.rgb.shape == (480, 640, 3) and f.rgb.dtype == np.uint8
    assert f.depth.shape == (480, 640) and f.depth.dtype == np.float32
    assert f.instance_ids.shape == (480, 640) and f.instance_ids.dtype == np.uint16
    n = len(f.objects)
    assert n == 2
    assert f.masks.shape == (n, 480, 640) and f.masks.dtype == np.bool_
    assert f.masks_visib.shape == (n, 480, 640) and f.masks_visib.dtype == np.bool_
    assert f.cam_K.shape == (3, 3) and f.cam_K.dtype == np.float64
    np.testing.assert_allclose(f.cam_K, gen.cam_K)
    for k, o in enumerate(f.objects):
        assert o["obj_id"] == 1
        assert o["R"].shape == (3, 3) and o["t"].shape == (3,)
        np.testing.assert_allclose(o["R"] @ o["R"].T, np.eye(3), atol=1e-9)
        assert 0.2 < o["t"][2] < 3.0  # metres in front of the camera
        assert len(o["bbox_obj"]) == 4 and len(o["bbox_visib"]) == 4
        assert 0.0 <= o["visib_fract"] <= 1.0
        assert o["px_count_visib"] == int(f.masks_visib[k].sum())
        assert o["gt_id"] == k
        # The visible part lies inside the full mask; instance ids mark the visible pixels.
        assert not (f.masks_visib[k] & ~f.masks[k]).any()
        assert ((f.instance_ids == k + 1) <= f.masks[k]).all()
    assert (f.depth >= 0).all()
    assert f.objects[0]["px_count_visib"] + f.objects[1]["px_count_visib"] > 0


def test_same_seed_same_arrays(gen: synthgen.Generator) -> None:
    again = synthgen.Generator(**gen.kwargs)
    for i in (0, 3, 5):
        assert same(gen[i], again[i])
    other = synthgen.Generator(**dict(gen.kwargs, seed=gen.seed + 1))
    assert not np.array_equal(gen[0].rgb, other[0].rgb)


def test_frame_i_does_not_depend_on_order_threads_or_batches(
    gen: synthgen.Generator,
) -> None:
    one = [gen[i] for i in range(len(gen))]
    batch = gen.batch([4, 1, 5])
    assert [same(a, b) for a, b in zip(batch, [one[4], one[1], one[5]])] == [True] * 3
    single_thread = synthgen.Generator(**dict(gen.kwargs, threads=1))
    assert all(same(a, b) for a, b in zip(single_thread, one))
    assert all(same(a, b) for a, b in zip(gen[1:4], one[1:4]))
    assert same(gen[-1], one[-1])
    assert [f.index for f in gen] == list(range(len(gen)))


def test_frame_ranges_index_globally(gen: synthgen.Generator) -> None:
    tail = gen.with_frames(range(4, 6))
    assert len(tail) == 2 and tail.frame_indices == range(4, 6)
    assert same(tail[0], gen[4]) and tail[0].index == 4


def test_out_of_range(gen: synthgen.Generator) -> None:
    with pytest.raises(IndexError):
        gen[len(gen)]
    with pytest.raises(IndexError):
        gen[-len(gen) - 1]


def test_pickles_by_its_arguments(gen: synthgen.Generator) -> None:
    back = pickle.loads(pickle.dumps(gen))
    assert back.kwargs == gen.kwargs and same(back[2], gen[2])
    f = pickle.loads(pickle.dumps(gen[2]))
    assert same(f, gen[2])


def test_rendering_releases_the_gil(gen: synthgen.Generator) -> None:
    ticks = 0
    stop = threading.Event()

    def count() -> None:
        nonlocal ticks
        while not stop.is_set():
            ticks += 1
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    time.sleep(0.05)
    # One native call: were the GIL held through it, the counter could not run meanwhile.
    big = gen.with_frames(40)
    before, started = ticks, time.monotonic()
    big.batch(range(40))
    elapsed, during = time.monotonic() - started, ticks - before
    stop.set()
    t.join()
    assert elapsed > 0.05, "too fast to tell"
    assert during > 10, f"{during} ticks in {elapsed:.2f} s"


def test_objects_and_spec(gen: synthgen.Generator) -> None:
    assert [o[0] for o in gen.objects] == [1, 1]
    assert "linemod" in gen.spec_toml()
    assert gen.image_size == (640, 480)
    assert "Generator 6 frames" in repr(gen)
