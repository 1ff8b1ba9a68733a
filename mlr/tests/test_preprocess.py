"""Preprocessing: the normalisation and its inverse, and the seeded 70/20/10 split."""
import numpy as np
import pytest

from mlr.pickler import Samples
from mlr.preprocess import Normalizer, load_prepared, prepare, save_prepared, split_indices


def samples(n=1000, seed=1):
    rng = np.random.default_rng(seed)
    x = rng.normal(3.0, 2.0, size=(n, 5))
    x[:, 4] = 7.0  # a constant column
    y = rng.normal(size=(n, 3))
    return Samples(x, y, np.full(n, 2.0), np.zeros(n, dtype=int), np.arange(n), ["s"])


def test_mean_removal_and_largest_absolute_value_scaling_and_its_inverse():
    x = np.array([[1.0, 10.0, 5.0], [3.0, 30.0, 5.0], [8.0, 20.0, 5.0]])
    norm = Normalizer.fit(x)
    np.testing.assert_allclose(norm.mean, [4.0, 20.0, 5.0])
    np.testing.assert_allclose(norm.scale, [4.0, 10.0, 1.0])  # constant column: scale 1, not a division by 0
    scaled = norm.apply(x)
    assert np.abs(scaled).max(axis=0).tolist() == [1.0, 1.0, 0.0]
    np.testing.assert_allclose(scaled.mean(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(norm.invert(scaled), x)


def test_the_split_is_seeded_disjoint_complete_and_70_20_10():
    parts = split_indices(1000, (0.7, 0.2, 0.1), seed=3)
    assert [len(p) for p in parts] == [700, 200, 100]
    joined = np.concatenate(parts)
    assert sorted(joined.tolist()) == list(range(1000))
    assert all(np.array_equal(a, b) for a, b in zip(parts, split_indices(1000, (0.7, 0.2, 0.1), seed=3), strict=True))
    assert not np.array_equal(parts[0], split_indices(1000, (0.7, 0.2, 0.1), seed=4)[0])
    assert not np.array_equal(parts[0], np.arange(700))  # shuffled


def test_prepare_takes_statistics_from_the_training_part_and_keeps_raw_labels(tmp_path):
    data = samples()
    prepared = prepare(data, seed=5)
    train = split_indices(len(data), (0.7, 0.2, 0.1), 5)[0]
    np.testing.assert_allclose(prepared.x_norm.mean, data.x[train].mean(axis=0))
    test = split_indices(1000, (0.7, 0.2, 0.1), 5)[2]
    np.testing.assert_allclose(prepared.x_norm.invert(prepared.test.x), data.x[test], atol=1e-5)
    np.testing.assert_allclose(prepared.y_norm.invert(prepared.val.y), prepared.val.y_raw, atol=1e-5)
    assert prepared.train.x.dtype == np.float32 and np.abs(prepared.train.x).max() <= 1.0 + 1e-6
    save_prepared(prepared, tmp_path / "p.npz")
    again = load_prepared(tmp_path / "p.npz")
    np.testing.assert_array_equal(again.test.x, prepared.test.x)
    np.testing.assert_array_equal(again.y_norm.scale, prepared.y_norm.scale)


def test_too_few_samples_are_refused_with_a_hint():
    with pytest.raises(ValueError, match="only 3 samples: too few .* check role, algorithm and datasets"):
        prepare(samples(3))
