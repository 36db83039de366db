"""Single-frame attitude determination (adcs_controllers.estimators.single_frame): TRIAD, the q-method
and QUEST against scipy's ``Rotation.align_vectors`` on noiseless vectors, their error statistics
against the QUEST measurement model's covariance on noisy ones, and degenerate input (fuzzed).

The statistical check: with ``N`` seeded trials of Gaussian sensor noise the small-angle errors
``δθ_k`` should be N(0, P). Whitened by ``P = L Lᵀ`` (``z_k = L⁻¹ δθ_k``), their sample covariance
``Ŝ = (1/N) Σ z_k z_kᵀ`` (known zero mean) is tested against ``I`` by the likelihood-ratio statistic
``N (tr Ŝ − ln det Ŝ − 3)``, asymptotically χ² with 6 degrees of freedom (Anderson, *An Introduction
to Multivariate Statistical Analysis*, §10.8). The bound is its 0.999 quantile (22.46): a correct
model fails with probability 0.1 % for a random seed (the seeds are fixed, so the test is
deterministic). The same statistic with P scaled by 1.2 must exceed the bound, so the test can fail.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from adcs_controllers.estimators.single_frame import davenport_k, q_method, quest, quest_covariance, triad
from adcs_core.attitude import rotate_to_body

N_TRIALS = 2000
LR_BOUND = chi2.ppf(0.999, 6)


def angle_between(qa, qb):
    """Rotation angle (rad) between two attitudes, sign-independent."""
    return (Rotation.from_quat(np.reshape(qa, (-1, 4))).inv() * Rotation.from_quat(np.reshape(qb, (-1, 4)))).magnitude()


def scenario(n_batch, n_vec, seed):
    rng = np.random.default_rng(seed)
    q = Rotation.random(n_batch, random_state=seed).as_quat()
    r = rng.normal(size=(n_batch, n_vec, 3))
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    b = rotate_to_body(q[:, None, :], r)
    w = rng.uniform(0.2, 3.0, size=(n_batch, n_vec))
    return q, b, r, w


def scipy_estimate(b, r, w):
    """scipy's estimate: align_vectors(a, b) finds C with a ≈ C b; here r ≈ R b, R body to inertial."""
    return np.stack([Rotation.align_vectors(r[i], b[i], weights=w[i])[0].as_quat() for i in range(len(b))])


# --- noiseless: equal to align_vectors --------------------------------------------------------------

@pytest.mark.parametrize('n_vec', [2, 3, 4, 7])
@pytest.mark.parametrize('estimator', [q_method, quest])
def test_wahba_solvers_equal_align_vectors_batched_and_single(estimator, n_vec):
    q, b, r, w = scenario(400, n_vec, seed=10 + n_vec)
    ref = scipy_estimate(b, r, w)
    batched = estimator(b, r, w)
    assert batched.shape == (400, 4)
    assert angle_between(batched, ref).max() < 1e-12
    assert angle_between(batched, q).max() < 1e-12
    single = np.stack([estimator(b[i], r[i], w[i]) for i in range(0, 400, 37)])
    assert single.shape == (len(range(0, 400, 37)), 4)
    assert angle_between(single, ref[::37]).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(batched, axis=-1), 1.0, atol=1e-15)
    assert (batched[:, 3] >= 0).all()


def test_quest_gives_each_element_of_a_batch_the_bits_it_gets_alone():
    """Newton's iteration for λmax stops per element (noisy vectors converge in different numbers of
    steps): an element of a batch is not iterated further because another has not converged."""
    q, b, r, w = scenario(200, 2, seed=31)
    b = b + np.random.default_rng(32).normal(scale=np.geomspace(1e-8, 1e-1, 200)[:, None, None], size=b.shape)
    batched = quest(b, r, w)
    for i in range(200):
        np.testing.assert_array_equal(batched[i], quest(b[i], r[i], w[i]), err_msg=f'element {i}')


def test_quest_covers_both_branches_near_180_degrees():
    """Rotations within a few degrees of 180° take the q-method fallback, the rest Newton + Gibbs:
    both equal align_vectors."""
    rng = np.random.default_rng(3)
    axis = rng.normal(size=(200, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.concatenate([np.full(100, np.pi), np.pi - rng.uniform(0, 0.3, 100)])
    q = Rotation.from_rotvec(axis * angle[:, None]).as_quat()
    r = rng.normal(size=(200, 3, 3))
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    b = rotate_to_body(q[:, None, :], r)
    w = np.ones(3)
    assert angle_between(quest(b, r, w), scipy_estimate(b, r, np.broadcast_to(w, (200, 3)))).max() < 1e-12


def test_triad_equals_align_vectors_and_trusts_the_first_vector():
    q, b, r, w = scenario(400, 2, seed=5)
    ref = scipy_estimate(b, r, w)
    est = triad(b[:, 0], r[:, 0], b[:, 1], r[:, 1])
    assert angle_between(est, ref).max() < 1e-12
    assert angle_between(triad(b[7, 0], r[7, 0], b[7, 1], r[7, 1]), ref[7]).max() < 1e-12
    # with a perturbed second vector, the first pair is still matched exactly
    b2 = b[:, 1] + 0.05 * np.random.default_rng(6).normal(size=(400, 3))
    est = triad(b[:, 0], r[:, 0], b2, r[:, 1])
    np.testing.assert_allclose(rotate_to_body(est, r[:, 0]), b[:, 0], atol=1e-14)


def test_k_matrix_eigenvalue_is_the_weight_sum_when_noiseless():
    """λmax = λ0 = Σ w_i (Wahba's loss zero) and K is symmetric and traceless."""
    _, b, r, w = scenario(50, 3, seed=8)
    K = davenport_k(b, r, w)
    np.testing.assert_allclose(K, np.swapaxes(K, -1, -2), atol=0)
    np.testing.assert_allclose(np.trace(K, axis1=-2, axis2=-1), 0, atol=1e-13)
    np.testing.assert_allclose(np.linalg.eigvalsh(K)[:, -1], w.sum(axis=-1), rtol=1e-13)


# --- noisy: the errors match the QUEST covariance ---------------------------------------------------

def noisy(b, sigma, rng):
    """Each body vector rotated by a small random rotation of rotation vector N(0, σ² I): its
    perpendicular error has covariance σ² (I − b bᵀ), Shuster's measurement model, and it stays unit."""
    rv = rng.normal(size=b.shape) * np.asarray(sigma)[..., None]
    return Rotation.from_rotvec(rv.reshape(-1, 3)).apply(b.reshape(-1, 3)).reshape(b.shape)


def error_vectors(q_est, q_true):
    """δθ (body axes): R_true = R_est exp([δθ×])."""
    return (Rotation.from_quat(q_est).inv() * Rotation.from_quat(q_true)).as_rotvec()


def lr_statistic(dtheta, P):
    L = np.linalg.cholesky(P)
    z = np.linalg.solve(L, dtheta[..., None])[..., 0]
    S = np.einsum('ki,kj->ij', z, z) / len(z)
    return len(z) * (np.trace(S) - np.log(np.linalg.det(S)) - 3.0)


CASES = [  # (n vectors, sigma per vector in rad, seed): from a few arcsec to 1 mrad
    (2, [2e-5, 1e-3], 21),
    (3, [1e-5, 1e-5, 1e-5], 22),
    (4, [1e-3, 5e-4, 2e-4, 1e-4], 23),
]


@pytest.mark.parametrize('n_vec,sigma,seed', CASES)
@pytest.mark.parametrize('estimator', [q_method, quest])
def test_error_statistics_match_the_quest_covariance(estimator, n_vec, sigma, seed):
    """One attitude and one geometry, N_TRIALS noise draws: the sample covariance of δθ is P."""
    rng = np.random.default_rng(seed)
    q_true = Rotation.random(random_state=seed).as_quat()
    r = rng.normal(size=(n_vec, 3))
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    b = rotate_to_body(q_true, r)
    P = quest_covariance(b, sigma)
    bm = noisy(np.broadcast_to(b, (N_TRIALS, n_vec, 3)), sigma, rng)
    est = estimator(bm, r, np.asarray(sigma) ** -2.0)
    dtheta = error_vectors(est, np.broadcast_to(q_true, (N_TRIALS, 4)))
    assert lr_statistic(dtheta, P) < LR_BOUND
    assert lr_statistic(dtheta, 1.2 * P) > LR_BOUND        # the test has the power to fail
    std_ratio = np.sqrt(np.diag(np.cov(dtheta.T, bias=True)) / np.diag(P))
    assert np.abs(std_ratio - 1).max() < 0.06              # 4 sigma of the ~1.6 % std of a std estimate


def test_quest_equals_q_method_on_noisy_vectors():
    rng = np.random.default_rng(30)
    q, b, r, w = scenario(500, 3, seed=30)
    bm = noisy(b, np.full(3, 1e-3), rng)
    assert angle_between(quest(bm, r, w), q_method(bm, r, w)).max() < 1e-12


# --- degenerate input ------------------------------------------------------------------------------

settings.register_profile('adcs-estimators', derandomize=True, max_examples=80, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow], database=None)

finite = st.floats(-1e3, 1e3, allow_nan=False)
anyfloat = st.one_of(finite, st.just(0.0), st.just(np.nan), st.just(np.inf), st.floats(-1e-9, 1e-9))
vec = st.lists(anyfloat, min_size=3, max_size=3)


def _valid_or_value_error(fn, *args):
    try:
        q = fn(*args)
    except ValueError as exc:
        assert str(exc)
        return None
    assert np.isfinite(q).all(), q
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    return q


@settings(settings.get_profile('adcs-estimators'))
@given(st.lists(st.tuples(vec, vec, st.one_of(st.floats(0, 10), st.just(0.0), st.just(-1.0), st.just(np.nan))),
                min_size=1, max_size=4), st.booleans())
def test_fuzz_wahba_solvers(pairs, parallel):
    b = np.array([p[0] for p in pairs], dtype=float)
    r = np.array([p[1] for p in pairs], dtype=float)
    w = np.array([p[2] for p in pairs], dtype=float)
    if parallel:       # every body vector along the first one (scaled): unobservable if finite
        b = b[:1] * np.arange(1, len(b) + 1)[:, None]
    for fn in (q_method, quest):
        _valid_or_value_error(fn, b, r, w)
    try:
        assert np.isfinite(davenport_k(b, r, w)).all()
    except ValueError as exc:
        assert str(exc)


@settings(settings.get_profile('adcs-estimators'))
@given(vec, vec, vec, vec)
def test_fuzz_triad(b1, r1, b2, r2):
    _valid_or_value_error(triad, b1, r1, b2, r2)


@pytest.mark.parametrize('case,match', [
    (dict(b=[[1, 0, 0], [2, 0, 0]]), 'unobservable'),                 # parallel body vectors
    (dict(r=[[0, 1, 0], [0, -3, 0]]), 'unobservable'),                # antiparallel reference vectors
    (dict(w=[1.0, 0.0]), 'unobservable'),                             # the only other vector weighted 0
    (dict(w=[0.0, 0.0]), 'unobservable'),
    (dict(w=[1.0, -1.0]), 'negative'),
    (dict(w=[1.0, np.nan]), 'non-finite'),
    (dict(b=[[np.nan, 0, 0], [0, 1, 0]]), 'non-finite'),
    (dict(b=[[0, 0, 0], [0, 1, 0]]), 'zero-length'),
    (dict(b=[[1, 0, 0], [0, 1, 0], [0, 0, 1]]), 'shapes'),         # 3 body vectors, 2 reference ones
])
def test_bad_input_is_a_clear_value_error(case, match):
    args = dict(b=[[1, 0, 0], [0, 1, 0]], r=[[0, 0, 1], [1, 0, 0]], w=[1.0, 1.0]) | case
    for fn in (q_method, quest, davenport_k):
        with pytest.raises(ValueError, match=match):
            fn(args['b'], args['r'], args['w'])


def test_non_unit_vectors_are_directions():
    q, b, r, w = scenario(20, 3, seed=40)
    scale = np.random.default_rng(41).uniform(1e-3, 1e3, size=(20, 3, 1))
    assert angle_between(quest(b * scale, r / scale, w), q).max() < 1e-12
    assert angle_between(triad(b[:, 0] * 7, r[:, 0], b[:, 1], r[:, 1] * 1e-4), q).max() < 1e-12


def test_triad_rejects_parallel_vectors_and_quest_covariance_bad_sigma():
    with pytest.raises(ValueError, match='parallel'):
        triad([1, 0, 0], [0, 1, 0], [-2, 0, 0], [0, 0, 1])
    with pytest.raises(ValueError, match='sigma'):
        quest_covariance([[1, 0, 0], [0, 1, 0]], [1e-3, 0.0])
    with pytest.raises(ValueError, match='unobservable'):
        quest_covariance([[1, 0, 0], [1, 0, 0]], [1e-3, 1e-3])
