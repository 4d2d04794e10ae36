"""Checks shared by the periodic-orbit tests, written independently of the code under test
where it matters: the chart (r1, r2), the rotation about the body axis 3, and the quotient
map's matrix from central differences of the real128 section integrator."""

import math

import numpy as np


def rotate_public(x, theta):
    """Rotation of omega, gamma, R about the body axis 3 by theta (written here, not taken
    from the module under test), in the state's own number type."""
    y = np.array(x, dtype=object)
    c, s = math.cos(theta), math.sin(theta)
    for b in (0, 3, 6):
        y[b], y[b + 1] = c * x[b] - s * x[b + 1], s * x[b] + c * x[b + 1]
    return y


def rr(pub):
    """(r1, r2) of a public state, written here (section 4: r1 = R1 g1 + R2 g2,
    r2 = R1 g2 - R2 g1), in the state's own number type."""
    R1, R2, g1, g2 = pub[6], pub[7], pub[3], pub[4]
    return np.array([R1 * g1 + R2 * g2, R1 * g2 - R2 * g1], dtype=object)


def quotient_matrix_fd(o, ball, levels, h=1e-6):
    """The 2x2 matrix of a symmetric ball's map of (r1, r2) at the relative periodic orbit
    ``o`` (``P^k``, section ``o.g0``): central differences along two tangent directions of
    section and level, every image by the real128 section integrator, ``J C^-1`` (J: d(r1,
    r2)(P^k x)/ds, C: d(r1, r2)(x)/ds). (r1, r2) are invariant under the rotation about axis
    3, so this is the quotient map in a chart; its trace and determinant are those of the
    variational multiplier matrix. ``h``: truncation ~h^2 |P'''|, rounding ~1e-34/h."""
    import heyoka as hy

    import taylorball as tb
    from taylorball import periodic as P

    probq = o.problem.replace(spec=tb.numbers.resolve_fp_type(hy.real128), tol=None)
    geo = P._eval_geo(o.problem, o.g0, o.internal)
    tq = P._level_targets(probq, geo.names, levels)
    ctxq = P._Ctx(probq, o.g0, 1, o.k, probq.spec.array([tq[n] for n in geo.names]), True, 1e4)
    G = np.vstack([geo.grad_e[None, :], geo.grad_c])
    V = np.linalg.svd(G)[2][G.shape[0]:].T  # 3 tangent directions of section and level
    xq = probq.spec.array(o.internal)
    J, C = np.zeros((2, 2)), np.zeros((2, 2))
    for j in range(2):
        img, dom = [], []
        for sgn in (1, -1):
            xs = P._to_level(ctxq, xq + probq.spec.array(sgn * h * V[:, j]), 20.0)
            p = P.public_state(probq.system, probq.pars, xs, probq.spec)
            sec = tb.poincare_section("reduced", ball, p, n_points=o.k, g0=o.g0, fp_type=hy.real128)
            img.append(rr(sec.states[-1]))
            dom.append(rr(p))
        J[:, j] = (img[0] - img[1]).astype(float) / (2 * h)
        C[:, j] = (dom[0] - dom[1]).astype(float) / (2 * h)
    return J @ np.linalg.inv(C)


def polyline_distance(p, C):
    """Distance from p to the polyline C (rows with NaN skipped)."""
    best = np.inf
    for a, b in zip(C[:-1], C[1:]):
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        d = b - a
        t = np.clip(np.dot(p - a, d) / max(np.dot(d, d), 1e-300), 0.0, 1.0)
        best = min(best, float(np.linalg.norm(p - (a + t * d))))
    return best
