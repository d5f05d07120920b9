"""The solver's compiled core (numba): the contact fit's search, and the labelling of the
contacts it fits.

The contact fit (:class:`solver.efficiency.ContactFit`) is a Gauss-Newton
search over each contact's shear pair whose every trial is a non-negative
least-squares problem ``argmin_{g >= 0} |A g - b|`` on about 120 sensors and
150 sub-cell columns, each differing only a little from the last. Lawson and
Hanson's active-set method fits that case when it starts from a guessed
positive set and updates the Cholesky factor of that set's Gram matrix as
columns come and go: adding a column costs one triangular solve, removing
one a sweep of Givens rotations, where solving each set afresh costs a
factorization. The Gauss-Newton step then reuses that factor to eliminate
the profile. ``scipy.optimize.nnls`` has neither a warm start nor updates,
and in numpy each fit costs hundreds of calls of a few microseconds, so the
whole search is compiled here, and with it the per-frame bookkeeping around
it (the contacts of the normal-only solution, the gather of their columns,
the patches of the load decision, the template and what it leaves of the
data), which in scipy cost about 0.1 ms of calls. A fit the updated factor
cannot take to its optimum (a full set, or a cap on the set changes) is
finished by scipy when it is the answer
(:func:`scipy_fit`, from ``ContactFit.fit``); inside the search it ends the
search at the last optimal fit. ``docs/efficiency.md`` has the measurements
that justify the compiled code.

Everything compiled lives in this one module: numba's on-disk cache checks
only the file a function is defined in, so a compiled caller in another
file could keep running an old version of a function changed here.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.optimize import lsq_linear, nnls

__all__ = ["contact_cores", "faint_cores", "laplacian_noise", "contact_labels", "contact_reach",
           "halved_labels", "fit_view", "template_misfit", "contact_stress", "load_patches", "near_sums",
           "misfit_variance", "shear_evidence", "load_decision", "scipy_fit", "workspace", "lawson_hanson",
           "fit_at", "gauss_newton", "pairs_of", "BOTH", "RATIO", "DIRECTION"]


# Columns whose remaining norm after projecting out the set's columns is below this fraction
# of their own norm are taken as dependent: the factor could not stay positive definite.
_DEPENDENT = 1e-12
# The optimality test's relative size (lawson_hanson).
_OPTIMAL = 1e-12
# Most columns entering the set at once (lawson_hanson).
_ENTERING = 8


def scipy_fit(matrix, stress):
    """The fallback: ``scipy.optimize.nnls``, and bounded least squares if it runs out of
    iterations on a degenerate problem."""
    try:
        return nnls(matrix, stress, maxiter=30 * max(matrix.shape[1], 1))[0]
    except RuntimeError:
        return lsq_linear(matrix, stress, bounds=(0.0, np.inf), method="bvls").x


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _dot(x, y):
    # reassociation lets LLVM vectorize the sum; these are the method's inner products
    total = 0.0
    for r in range(x.shape[0]):
        total += x[r] * y[r]
    return total


@numba.njit(cache=True, nogil=True, fastmath={"contract"})
def _axpy(a, x, y):
    # y += a x in place (no temporary)
    for r in range(x.shape[0]):
        y[r] += a * x[r]


@numba.njit(cache=True, nogil=True)
def _append(factor, k, gram, diagonal):
    # Border the k x k lower factor with a column whose Gram entries with the set are ``gram``:
    # row k is L^-1 gram and the new diagonal what is left of the column's squared norm.
    border = factor[k]
    _forward(factor, k, gram, border, 0)
    rest = diagonal - _dot(border[:k], border[:k])
    if rest <= _DEPENDENT * diagonal:
        return False
    factor[k, k] = np.sqrt(rest)
    return True


@numba.njit(cache=True, nogil=True)
def _remove(factor, k, p):
    # Drop row and column p of the k x k factor: the rows below move up and are then lower
    # Hessenberg; Givens rotations on column pairs (i, i + 1) make them triangular again.
    for i in range(p, k - 1):
        for j in range(i + 2):
            factor[i, j] = factor[i + 1, j]
    for i in range(p, k - 1):
        a, b = factor[i, i], factor[i, i + 1]
        radius = np.hypot(a, b)
        c, s = a / radius, b / radius
        for t in range(i, k - 1):
            x, y = factor[t, i], factor[t, i + 1]
            factor[t, i] = c * x + s * y
            factor[t, i + 1] = c * y - s * x
    for i in range(k):
        factor[i, k - 1] = 0.0
        factor[k - 1, i] = 0.0


@numba.njit(cache=True, nogil=True)
def _enter(columns, j, factor, index, free, k, gram, norm2):
    # column j enters the set as its (k+1)-th: the factor bordered with its Gram row; False (and
    # nothing changed) when it depends on the set
    for i in range(k):
        gram[i] = _dot(columns[index[i]], columns[j])
    if not _append(factor, k, gram, norm2):
        return False
    index[k] = j
    free[j] = True
    return True


@numba.njit(cache=True, nogil=True)
def _leave(factor, index, free, k, i):
    # the set's i-th column leaves it: out of the factor, the order and the mask; returns k - 1
    free[index[i]] = False
    _remove(factor, k, i)
    for t in range(i, k - 1):
        index[t] = index[t + 1]
    return k - 1


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _forward(factor, k, rhs, y, start):
    # L y = rhs from row ``start`` on (the rows above are kept: a column entering the set
    # borders the factor and leaves them as they were), by inner products along the rows
    for i in range(start, k):
        total = rhs[i]
        for j in range(i):
            total -= factor[i, j] * y[j]
        y[i] = total / factor[i, i]


@numba.njit(cache=True, nogil=True, fastmath={"contract"})
def _backward(factor, k, y, z):
    # L^T z = y, subtracting each z_i times row i of L (contiguous) from the entries before it
    for i in range(k):
        z[i] = y[i]
    for i in range(k - 1, -1, -1):
        z[i] /= factor[i, i]
        zi = z[i]
        for j in range(i):
            z[j] -= factor[i, j] * zi


@numba.njit(cache=True, nogil=True)
def _solve(factor, k, rhs, z):
    # (L L^T) z = rhs by two triangular solves
    _forward(factor, k, rhs, z, 0)
    _backward(factor, k, z, z)


@numba.njit(cache=True, nogil=True)
def workspace(columns):
    """The factor and set buffers of :func:`lawson_hanson` for ``columns`` (n, R)."""
    size = min(columns.shape[0], columns.shape[1])
    return np.zeros((size + 1, size + 1)), np.empty(size + 1, np.int64)


@numba.njit(cache=True, nogil=True)
def lawson_hanson(columns, b, free, max_steps, g, factor, index):
    # Lawson-Hanson from the guessed set ``free`` (changed in place: the final set); the
    # answer goes to g, the set's Cholesky factor to factor[:k, :k] and its columns to
    # index[:k]. Returns (changes of the set made, k); the changes are -1 when the method
    # stopped short of the optimum (a full set, or more than max_steps changes): g is then
    # feasible, not optimal. A column dependent on the set never enters it.
    n, rows = columns.shape
    size = min(rows, n)
    gram = np.empty(size + 1)
    rhs = np.empty(size + 1)
    z = np.empty(size + 1)
    forward = np.empty(size + 1)                  # L^-1 A_S^T b on its first ``valid`` entries
    valid = 0
    correlation = np.empty(n)                     # A^T b
    norm2 = np.empty(n)
    barred = np.zeros(n, np.bool_)
    residual = np.empty(rows)
    for j in range(n):
        g[j] = 0.0
        correlation[j] = _dot(columns[j], b)
        norm2[j] = _dot(columns[j], columns[j])
    # A column's slope a_j . r counts as zero below _OPTIMAL |a_j| |b|: far above its rounding,
    # far below any slope that moves the fit. A looser test (1e-10 n max|A^T b|, once used here)
    # stopped where the residual is flat but the profile is not, so the answer depended on the
    # starting set by up to 31% of a node's force.
    scale = _OPTIMAL * np.sqrt(_dot(b, b))
    k = 0
    guess = np.flatnonzero(free)
    free[:] = False
    if 0 < guess.size <= size:
        # the guessed set's factor at once (BLAS and LAPACK) unless one of its columns depends
        # on the others; then column by column below, which leaves such columns out
        block = columns[guess]
        try:
            lower = np.linalg.cholesky(block @ block.T)
            independent = True
            for i in range(guess.size):
                independent &= lower[i, i] ** 2 > _DEPENDENT * norm2[guess[i]]
            if independent:
                k = guess.size
                factor[:k, :k] = lower
                index[:k] = guess
                free[guess] = True
        except Exception:  # not positive definite
            pass
    if k == 0:
        for j in guess:
            if k < size and _enter(columns, j, factor, index, free, k, gram, norm2[j]):
                k += 1
    steps = 0
    # a guessed set: drop the variables its least-squares solution does not keep positive
    while k > 0:
        for i in range(k):
            rhs[i] = correlation[index[i]]
        _forward(factor, k, rhs, forward, valid)
        _backward(factor, k, forward, z)
        valid = k
        dropped = False
        for i in range(k - 1, -1, -1):
            if z[i] <= 0:
                dropped = True
                k = _leave(factor, index, free, k, i)
                valid = min(valid, i)
        if not dropped:
            for i in range(k):
                g[index[i]] = z[i]
            break
        steps += 1
        if steps > max_steps:
            return -1, k
    chosen = np.empty(_ENTERING, np.int64)
    height = np.empty(_ENTERING)
    while True:
        # optimal on the set: the variables outside it with the steepest descent enter, up to
        # _ENTERING of them at once (each scan of the columns costs n R, as much as the rest of a
        # step; one at a time, a cold fit of a few contacts took 200 scans)
        for r in range(rows):
            residual[r] = b[r]
        for i in range(k):
            _axpy(-g[index[i]], columns[index[i]], residual)
        before = k
        while True:
            found = 0
            for j in range(n):
                if not free[j] and not barred[j]:
                    slope = _dot(columns[j], residual)
                    if slope <= scale * np.sqrt(norm2[j]):
                        continue
                    if found < _ENTERING:
                        at = found
                        found += 1
                    elif slope > height[_ENTERING - 1]:
                        at = _ENTERING - 1
                    else:
                        continue
                    while at > 0 and height[at - 1] < slope:  # kept in decreasing order of slope
                        height[at], chosen[at] = height[at - 1], chosen[at - 1]
                        at -= 1
                    height[at], chosen[at] = slope, j
            if found == 0:
                return steps, k
            for c in range(found):
                if k >= size:
                    break
                j = chosen[c]
                if _enter(columns, j, factor, index, free, k, gram, norm2[j]):
                    k += 1
                else:
                    barred[j] = True
            if k > before:
                break
            if k >= size:
                return -1, k
        steps += 1
        if steps > max_steps:
            return -1, k
        # entrants the least squares on the enlarged set does not keep positive leave again (they
        # are at zero: the fit is unchanged; all of them but the steepest when none comes out
        # positive, and the steepest alone comes out positive but for rounding), so every
        # entrant left moves the fit downhill and the set never cycles
        while k > before + 1:
            for i in range(k):
                rhs[i] = correlation[index[i]]
            _forward(factor, k, rhs, forward, valid)
            _backward(factor, k, forward, z)
            valid = k
            bad = 0
            for i in range(before, k):
                bad += z[i] <= 0
            if bad == 0:
                break
            for i in range(k - 1, before - 1, -1):
                if (z[i] <= 0 if bad < k - before else i > before):
                    k = _leave(factor, index, free, k, i)
                    valid = min(valid, i)
        entering = index[before]
        # least squares on the set; while a variable is not positive, step from the current g
        # (feasible) towards it until the first variable reaches zero, and drop those at zero
        entered = True
        while True:
            for i in range(k):
                rhs[i] = correlation[index[i]]
            _forward(factor, k, rhs, forward, valid)
            _backward(factor, k, forward, z)
            valid = k
            if entered and k == before + 1 and z[k - 1] <= 0:
                # rounding: the entering column does not come out positive; it would only
                # enter again and again, so it is barred (as scipy does)
                k -= 1
                valid = k
                free[entering] = False
                barred[entering] = True
                break
            entered = False
            blocking = -1
            step = 1.0
            for i in range(k):
                if z[i] <= 0:
                    current = g[index[i]]
                    ratio = current / max(current - z[i], 1e-300)
                    if blocking < 0 or ratio < step:
                        step, blocking = ratio, i
            if blocking < 0:
                for i in range(k):
                    g[index[i]] = z[i]
                break
            steps += 1
            if steps > max_steps:
                return -1, k
            for i in range(k):
                current = g[index[i]]
                g[index[i]] = current + step * (z[i] - current)
            g[index[blocking]] = 0.0
            for i in range(k - 1, -1, -1):
                if g[index[i]] <= 0:
                    g[index[i]] = 0.0
                    k = _leave(factor, index, free, k, i)
                    valid = min(valid, i)
            barred[:] = False  # a smaller set: what depended on it, or failed to enter, may now


@numba.njit(cache=True, nogil=True)
def _components(kind, indptr, indices, labels):
    # connected components of the nodes of kind >= 0, linked over the CSR adjacency when of the
    # same kind: labels 1..K in the order of each component's first node (raster order on a
    # grid), 0 elsewhere; returns K
    return _linked_components(kind, indptr, indices, np.empty((0, 2)), np.inf, labels)


@numba.njit(cache=True, nogil=True)
def _linked_components(kind, indptr, indices, positions, reach2, labels):
    # _components, linking only nodes at most sqrt(reach2) apart (no test when reach2 is inf)
    m = kind.size
    stack = np.empty(m, np.int64)
    count = 0
    labels[:] = 0
    for seed in range(m):
        if kind[seed] < 0 or labels[seed] > 0:
            continue
        count += 1
        labels[seed] = count
        stack[0] = seed
        top = 1
        while top > 0:
            top -= 1
            here = stack[top]
            for e in range(indptr[here], indptr[here + 1]):
                there = indices[e]
                if kind[there] != kind[seed] or labels[there] != 0:
                    continue
                if reach2 < np.inf:
                    dx = positions[there, 0] - positions[here, 0]
                    dy = positions[there, 1] - positions[here, 1]
                    if dx * dx + dy * dy > reach2:
                        continue
                labels[there] = count
                stack[top] = there
                top += 1
    return count


# A patch carrying less than this share of the largest core's load is a speck of noise, not a contact.
_SPECK = 0.05


@numba.njit(cache=True, nogil=True)
def contact_cores(values, threshold, adjacent, labels):
    """The patches of a field that may be contacts: the one rule for finding them.

    The core is every node above ``threshold`` of the peak; of its connected
    patches only those holding at least 5% of the largest patch's sum are
    kept (isolated noise spikes are dropped).

    Parameters
    ----------
    values : (m,) ndarray
        The field: a normal-only solution (newtons) or the stress itself.
    threshold : float
        Fraction of the peak.
    adjacent : tuple of two (.,) ndarrays of int
        ``(indptr, indices)`` of the CSR matrix linking nodes of a patch (8
        neighbours on a grid).
    labels : (m,) ndarray of int
        Written: patch 1..K of each core node, 0 elsewhere.

    Returns
    -------
    kept : (K + 1,) ndarray of bool
        Whether each patch is kept (``kept[0]``, outside the core, is False).
    """
    m = values.size
    peak = -np.inf
    for i in range(m):
        peak = max(peak, values[i])
    if not peak > 0:
        labels[:] = 0
        return np.zeros(1, np.bool_)
    count = _components(np.where(values > threshold * peak, 0, -1), adjacent[0], adjacent[1], labels)
    mass = np.zeros(count + 1)
    for i in range(m):
        if labels[i] > 0:
            mass[labels[i]] += values[i]
    largest = mass[1:].max() if count > 0 else 0.0
    kept = mass >= _SPECK * largest
    kept[0] = False
    return kept


@numba.njit(cache=True, nogil=True)
def faint_cores(values, threshold, low, adjacent, labels):
    """Loads the frame's core misses: a broad light contact beside a sharp one.

    :func:`contact_cores` keeps the nodes above ``threshold`` of the frame's
    peak; a flat or broad load whose nodes each carry less (a palm beside a
    fingertip) keeps a node or none. Of the connected patches above ``low``
    of the peak, one whose core nodes hold less than half of its load and
    whose own peak is below the frame's is a candidate: its nodes above
    ``threshold`` of its own peak, when they carry 5% of the largest core's
    load or more (as :func:`contact_cores` keeps patches). Whether it is
    load or noise is the caller's to decide
    (:meth:`solver.inverse.DenseSolver.faint_contacts`).

    Parameters
    ----------
    values : (m,) ndarray
        The normal-only solution, newtons.
    threshold, low : float
        Fractions of the peak: the core's, and the patches'.
    adjacent : tuple of two (.,) ndarrays of int
        As for :func:`contact_cores`.
    labels : (m,) ndarray of int
        Written: candidate 1..J of each of its nodes, 0 elsewhere.

    Returns
    -------
    int
        ``J``.
    """
    m = values.size
    labels[:] = 0
    peak = -np.inf
    for i in range(m):
        peak = max(peak, values[i])
    if not peak > 0:
        return 0
    patches = np.empty(m, np.int64)
    count = _components(np.where(values > low * peak, 0, -1), adjacent[0], adjacent[1], patches)
    total, cored, top = np.zeros(count + 1), np.zeros(count + 1), np.zeros(count + 1)
    for i in range(m):
        p = patches[i]
        if p > 0:
            total[p] += values[i]
            top[p] = max(top[p], values[i])
            if values[i] > threshold * peak:
                cored[p] += values[i]
    own = np.zeros(count + 1)
    for i in range(m):
        p = patches[i]
        if p > 0 and values[i] > threshold * top[p]:
            own[p] += values[i]
    # the largest core's load: of the connected patches above threshold, as contact_cores weighs them
    cores = np.empty(m, np.int64)
    found = _components(np.where(values > threshold * peak, 0, -1), adjacent[0], adjacent[1], cores)
    mass = np.zeros(found + 1)
    for i in range(m):
        mass[cores[i]] += values[i] if cores[i] > 0 else 0.0
    largest = mass[1:].max() if found > 0 else 0.0
    for i in range(m):
        p = patches[i]
        if not (p > 0 and cored[p] < 0.5 * total[p] and top[p] < peak and own[p] >= _SPECK * largest
                and values[i] > threshold * top[p]):
            patches[i] = 0
    return _consecutive(patches, count + 1, labels)


@numba.njit(cache=True, nogil=True)
def laplacian_noise(image):
    """The sensors' noise deviation from one frame of a regular grid (:func:`solver.seen_frame.noise_level`).

    ``image`` (ny, nx), both at least 3: the robust deviation (1.4826 times
    the median absolute deviation) of the 5-point Laplacian at the inner
    nodes, over the Laplacian's ``sqrt(20)`` gain on independent noise.
    """
    ny, nx = image.shape
    laplacian = np.empty((ny - 2) * (nx - 2))
    k = 0
    for i in range(1, ny - 1):
        for j in range(1, nx - 1):
            laplacian[k] = (4 * image[i, j] - image[i - 1, j] - image[i + 1, j] - image[i, j - 1]
                            - image[i, j + 1])
            k += 1
    middle = np.median(laplacian)
    return 1.4826 * np.median(np.abs(laplacian - middle)) / math.sqrt(20.0)


# Two touching pieces of load are two contacts only when the smaller's core carries at least
# this share of the larger's. Chosen on the load-decision frames of seeds 1 to 3 (at 0, 5 of 30
# single loads under 20% noise came apart, with pieces of 12-13% given the largest shear ratio;
# pinches' fingers carry 40% or more of each other); judged on seeds 11 to 13.
SEPARATE_MASS = 0.25
# A frame with more pieces than this that could stand apart is noise, not that many touches
# (pure noise on the same frames: 9 to 53 pieces); its touching pieces join, as before.
SEPARATE_MOST = 4
# Two touching pieces whose cores a dip to at most this fraction of the lower peak sets apart are
# two contacts whatever their height (a flat punch, whose peak is low for its load, two pitches
# from a Hertz load: a dip to 0.12 of its peak). Looser splits (SPLIT_SEPARATION) are left to the
# split test's evidence, where the two lobes of a sheared ring beside a cone (a dip to 0.71 of
# the lower) came apart with ratios 1.2 in opposite directions.
SEPARATE_DIP = 0.6


@numba.njit(cache=True, nogil=True)
def _root(parent, k):
    # union-find with path halving
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


@numba.njit(cache=True, nogil=True)
def _consecutive(key, keys, labels):
    # labels 1..K in raster order of each key's first node (key 0: none; keys bounds them, and
    # labels may be key itself); returns K
    number = np.zeros(keys, np.int64)
    count = 0
    for i in range(key.size):
        k = key[i]
        if k > 0 and number[k] == 0:
            count += 1
            number[k] = count
        labels[i] = number[k] if k > 0 else 0
    return count


@numba.njit(cache=True, nogil=True)
def _separate(values, core, separation, adjacent, labels):
    # The contacts of the kept core patches: a patch holding two peaks with a dip between them
    # (the highest path from one to the other sinks to at most ``separation`` of the lower peak)
    # holds two contacts. Nodes join in decreasing order of value (the watershed's merge tree):
    # a node that links pieces whose peaks both stand that far above it is on the ridge between
    # two contacts and goes to the piece of its highest neighbour; any other piece it links is
    # a bump of the one with the highest peak. Writes labels 1..K (raster order of each
    # contact's first node), 0 outside the cores; returns K.
    m = values.size
    order = np.argsort(-values)
    parent = np.arange(m + 1)
    peak = np.zeros(m + 1)
    piece = np.zeros(m, np.int64)
    roots = np.empty(m, np.int64)
    count = 0
    for i in order:
        if core[i] == 0:
            continue
        found = 0
        best, best_value = -1, -np.inf
        for e in range(adjacent[0][i], adjacent[0][i + 1]):
            j = adjacent[1][e]
            if j == i or piece[j] == 0:
                continue
            r = _root(parent, piece[j])
            if values[j] > best_value:
                best, best_value = r, values[j]
            new = True
            for q in range(found):
                if roots[q] == r:
                    new = False
            if new:
                roots[found] = r
                found += 1
        if found == 0:
            count += 1
            piece[i] = count
            peak[count] = values[i]
            continue
        distinct = 0
        highest = roots[0]
        for q in range(found):
            r = roots[q]
            if values[i] <= separation * peak[r]:
                distinct += 1
            if peak[r] > peak[highest]:
                highest = r
        if distinct >= 2:
            # a ridge node: the pieces stay apart; bumps join the highest piece
            for q in range(found):
                r = roots[q]
                if values[i] > separation * peak[r]:
                    parent[r] = highest
            piece[i] = _root(parent, best)
        else:
            for q in range(found):
                parent[roots[q]] = highest
            piece[i] = highest
    for i in range(m):
        if piece[i] > 0:
            piece[i] = _root(parent, piece[i])
    return _consecutive(piece, m + 1, labels)


@numba.njit(cache=True, nogil=True)
def contact_labels(normal, threshold, separation, positions, adjacent, margin, near, faint):
    """The contacts of a normal-only solution and the sensors near each.

    The kept patches of :func:`contact_cores` are split where a patch holds
    two peaks with a dip between them (two loads a pitch or two apart, which
    the layer's stress blurs into one patch but the normal-only solution
    keeps apart), and each contact grows by the margin; a node within the
    margin of several contacts goes to the one whose core is nearest, so
    contacts that touch stay apart and are fitted with their own parameters.
    Grown contacts that touch join unless a deep dip between their cores
    sets them apart (:data:`SEPARATE_DIP`, :data:`SEPARATE_MASS`); nodes a
    contact encloses whose normal-only load sums to compression (the middle
    of a flat punch on a thin layer) join it.

    Parameters
    ----------
    normal : (m,) ndarray
        Normal-only force of each node, newtons.
    threshold : float
        Fraction of the peak.
    separation : float
        Two peaks of one patch are two contacts when the highest path between
        them sinks to at most this fraction of the lower peak (0: never split
        a patch; 1: every local maximum is a contact).
    positions : (m, 2) ndarray
        Node positions, metres.
    adjacent, margin, near : tuple of two (.,) ndarrays of int
        ``(indptr, indices)`` of the CSR neighbourhoods: nodes linked in a
        patch (8 neighbours on a grid), the margin, and a contact's reach.
    faint : (m,) ndarray of bool
        Nodes of loads below ``threshold`` of the frame's peak that are
        contacts all the same (:func:`faint_cores` found them, the caller's
        noise test kept them): cores besides the kept patches.

    Returns
    -------
    labels : (m,) ndarray of int
        Contact 1..K of each node, 0 outside every contact.
    near : (m, K) ndarray of bool
        The sensors near each contact.
    """
    m = normal.size
    core = np.zeros(m, np.int64)
    kept = contact_cores(normal, threshold, adjacent, core)
    for i in range(m):
        if not kept[core[i]]:
            core[i] = 0
        if faint[i]:
            core[i] = 1
    cores = np.zeros(m, np.int64)
    count = _separate(normal, core, separation, adjacent, cores)
    labels = np.zeros(m, np.int64)
    distance = np.full(m, np.inf)
    for i in range(m):
        if cores[i] > 0:
            for e in range(margin[0][i], margin[0][i + 1]):
                j = margin[1][e]
                d = (positions[i, 0] - positions[j, 0]) ** 2 + (positions[i, 1] - positions[j, 1]) ** 2
                if d < distance[j]:
                    distance[j] = d
                    labels[j] = cores[i]
    # Grown contacts that touch stay two when the smaller carries SEPARATE_MASS of the larger's core
    # load and the dip between them is deep: both peaks reach ``threshold / separation`` of the
    # frame's (the dip between two cores is below ``threshold`` of the peak, so that is a dip of at
    # most ``separation`` of the lower peak), or the highest path between their cores sinks to at
    # most SEPARATE_DIP (or ``separation``, if less) of the lower peak. A lighter piece (a noise
    # spike beside a contact) or one a shallow dip sets off (a lobe of a contact under heavy noise)
    # joins its neighbour. (Until 2026-11-28 only the first: a flat punch, whose peak is low for
    # its load, merged with a load two pitches from it behind a dip to 3% of the frame's peak.)
    top, mass = np.zeros(count + 1), np.zeros(count + 1)
    # a faint core is a load of its own beside others, whatever its peak; its pieces (a noisy plateau's
    # bumps) are one load
    light = np.zeros(count + 1, np.bool_)
    for i in range(m):
        top[cores[i]] = max(top[cores[i]], normal[i])
        mass[cores[i]] += normal[i]
        light[cores[i]] |= faint[i]
    tallest = top[1:].max() if count > 0 else 0.0
    standing = separation * top >= threshold * tallest
    standing[0] = False
    # the touching pairs of pieces that stay two contacts, and the pieces that stand apart from one
    apart = np.zeros((count + 1, count + 1), np.bool_)
    dip = min(separation, SEPARATE_DIP)
    saddle = np.empty((0, 0))
    for i in range(m):
        for e in range(adjacent[0][i], adjacent[0][i + 1]):
            p, q = labels[i], labels[adjacent[1][e]]
            if separation <= 0 or p == 0 or q == 0 or p == q or apart[p, q]:
                continue
            if light[p] != light[q]:
                apart[p, q] = apart[q, p] = True
            elif not light[p] and min(mass[p], mass[q]) >= SEPARATE_MASS * max(mass[p], mass[q]):
                if standing[p] and standing[q]:
                    apart[p, q] = apart[q, p] = True
                else:
                    if saddle.shape[0] == 0:  # found once, when first needed
                        saddle = _saddles(normal, cores, count, adjacent)
                    if saddle[p, q] <= dip * min(top[p], top[q]):
                        apart[p, q] = apart[q, p] = standing[p] = standing[q] = True
    if np.count_nonzero(standing) > SEPARATE_MOST:  # bumps all over the skin: noise, not that many contacts
        apart[:] = False
    parent = np.arange(count + 1)
    for i in range(m):
        for e in range(adjacent[0][i], adjacent[0][i + 1]):
            p, q = labels[i], labels[adjacent[1][e]]
            if p == 0 or q == 0 or apart[p, q]:
                continue
            a, b = _root(parent, p), _root(parent, q)
            if a != b:
                parent[max(a, b)] = min(a, b)
    for i in range(m):
        if labels[i] > 0:
            labels[i] = _root(parent, labels[i])
    count = _consecutive(labels, count + 1, labels)
    _fill_holes(labels, normal, positions, adjacent)
    return labels, contact_reach(labels, count, near)


@numba.njit(cache=True, nogil=True)
def _saddles(values, cores, count, adjacent):
    # (count + 1, count + 1): for two cores, the highest level a path from one to the other keeps
    # to (the merge tree of every node in decreasing order of value: the level at which their
    # components first meet); -inf where no path joins them
    m = values.size
    saddle = np.full((count + 1, count + 1), -np.inf)
    parent = np.arange(m)
    holds = np.zeros((m, count + 1), np.bool_)  # the cores in each component, by its root
    seen = np.zeros(m, np.bool_)
    for i in np.argsort(-values):
        seen[i] = True
        holds[i, cores[i]] = cores[i] > 0
        for e in range(adjacent[0][i], adjacent[0][i + 1]):
            j = adjacent[1][e]
            if not seen[j]:
                continue
            a, b = _root(parent, i), _root(parent, j)
            if a == b:
                continue
            for p in range(1, count + 1):
                if holds[a, p]:
                    for q in range(1, count + 1):
                        if holds[b, q] and saddle[p, q] == -np.inf:
                            saddle[p, q] = saddle[q, p] = values[i]
            parent[b] = a
            for p in range(1, count + 1):
                holds[a, p] |= holds[b, p]
    return saddle


@numba.njit(cache=True, nogil=True)
def _outer(i, positions, indptr, indices):
    # whether node i is on the skin's outline: its neighbours leave a side open (a gap of more than
    # 120 deg between the directions to them, or fewer than three). Every node of a grid's border;
    # none inside a grid, a hexagonal layout or one whose nodes are a tenth of a pitch off place
    # (whose diagonal neighbours may fall out of reach: a count of neighbours was fooled by that)
    angles = np.empty(indptr[i + 1] - indptr[i])
    k = 0
    for e in range(indptr[i], indptr[i + 1]):
        j = indices[e]
        if j != i:
            angles[k] = math.atan2(positions[j, 1] - positions[i, 1], positions[j, 0] - positions[i, 0])
            k += 1
    if k < 3:
        return True
    angles = np.sort(angles[:k])
    gap = angles[0] + 2 * math.pi - angles[k - 1]
    for t in range(1, k):
        gap = max(gap, angles[t] - angles[t - 1])
    return gap > 2 * math.pi / 3


@numba.njit(cache=True, nogil=True)
def _fill_holes(labels, normal, positions, adjacent):
    # A contact's region has no holes that hold load: nodes outside every contact that no path of
    # such nodes links to the skin's outline (_outer), that touch one contact only and whose
    # normal-only load adds up to compression, join it. (The interior of a flat punch on a thin
    # layer falls below the threshold while its rim stands above; without its load inside, the
    # fit of the rim alone bent the contact's shear. A hole of noise sums to about nothing and is
    # left out: filled, the holes of a load under heavy noise took its region past the fit's budget.)
    m = labels.size
    indptr, indices = adjacent
    if m == 0 or labels.max() == 0:
        return
    # The nodes outside the contacts link only to their nearest (within 1.25 of the layout's
    # typical spacing: a grid's four, not its diagonals, which a contact's diagonal edge does not
    # block; the contacts' nodes link to their eight)
    nearest = np.full(m, np.inf)
    for i in range(m):
        if labels[i] == 0:  # (the contacts' nodes are enough to tell the spacing, and cheaper)
            continue
        for e in range(indptr[i], indptr[i + 1]):
            j = indices[e]
            if j != i:
                dx, dy = positions[j, 0] - positions[i, 0], positions[j, 1] - positions[i, 1]
                nearest[i] = min(nearest[i], math.sqrt(dx * dx + dy * dy))
    reach2 = (1.25 * np.median(nearest[np.isfinite(nearest)])) ** 2 if np.isfinite(nearest).any() else 0.0
    pieces = np.zeros(m, np.int64)
    count = _linked_components(np.where(labels == 0, 0, -1), indptr, indices, positions, reach2, pieces)
    owner = np.zeros(count + 1, np.int64)  # the one contact a piece touches; -1: outline or several
    for i in range(m):
        k = pieces[i]
        if k == 0 or owner[k] < 0:
            continue
        for e in range(indptr[i], indptr[i + 1]):
            c = labels[indices[e]]
            if c > 0:
                if owner[k] == 0:
                    owner[k] = c
                elif owner[k] != c:
                    owner[k] = -1
        if owner[k] >= 0 and _outer(i, positions, indptr, indices):
            owner[k] = -1
    load = np.zeros(count + 1)
    for i in range(m):
        load[pieces[i]] += normal[i]
    for i in range(m):
        if pieces[i] > 0 and owner[pieces[i]] > 0 and load[pieces[i]] > 0:
            labels[i] = owner[pieces[i]]


@numba.njit(cache=True, nogil=True)
def contact_reach(labels, count, near):
    """(m, count) ndarray of bool: the sensors within reach of each contact's nodes.

    ``labels`` (m,) numbers the contacts 1..count (0 outside them); ``near`` is the reach's CSR
    ``(indptr, indices)``, as for :func:`contact_labels`.
    """
    m = labels.size
    reach = np.zeros((m, count), np.bool_)
    for i in range(m):
        if labels[i] > 0:
            for e in range(near[0][i], near[0][i + 1]):
                reach[near[1][e], labels[i] - 1] = True
    return reach


@numba.njit(cache=True, nogil=True)
def halved_labels(normal, labels, at_edge, positions, elongation, near):
    """Elongated contacts halved across their long axis, and the sensors near each contact.

    A contact whose normal-only load (its positive part) spreads ``elongation`` times as far
    along its long axis as across it (the square root of the ratio of its second moments'
    eigenvalues) becomes two: its nodes on either side of the line through its centre of load
    across that axis. Contacts at the skin's border and of fewer than 4 nodes stay whole.

    Parameters
    ----------
    normal : (m,) ndarray
        Normal-only force of each node, newtons.
    labels : (m,) ndarray of int
        Contact 1..K of each node, 0 outside every contact (:func:`contact_labels`).
    at_edge : (K,) ndarray of bool
        The contacts at the skin's border.
    positions : (m, 2) ndarray
        Node positions, metres.
    elongation : float
        At least 1.
    near : tuple of two (.,) ndarrays of int
        ``(indptr, indices)`` of a contact's reach, as for :func:`contact_labels`.

    Returns
    -------
    labels : (m,) ndarray of int
        Contacts 1..K as before, the second halves numbered from K + 1 (``labels`` itself
        when none was halved).
    near : (m, K') ndarray of bool
        The sensors near each contact.
    """
    m, K = normal.size, at_edge.size
    moments = np.zeros((K + 1, 7))  # nodes, sum of w, w x, w y, w x^2, w x y, w y^2
    for i in range(m):
        k = labels[i]
        if k > 0:
            w, x, y = max(normal[i], 0.0), positions[i, 0], positions[i, 1]
            moments[k, 0] += 1
            moments[k, 1] += w
            moments[k, 2] += w * x
            moments[k, 3] += w * y
            moments[k, 4] += w * x * x
            moments[k, 5] += w * x * y
            moments[k, 6] += w * y * y
    split = np.zeros(K + 1, np.int64)  # the label of the second half, 0 where whole
    line = np.zeros((K + 1, 4))  # centre and long axis
    count = K
    for k in range(1, K + 1):
        total = moments[k, 1]
        if at_edge[k - 1] or moments[k, 0] < 4 or total <= 0:
            continue
        cx, cy = moments[k, 2] / total, moments[k, 3] / total
        a = moments[k, 4] / total - cx * cx
        b = moments[k, 5] / total - cx * cy
        c = moments[k, 6] / total - cy * cy
        half, gap = (a + c) / 2, math.sqrt(((a - c) / 2) ** 2 + b * b)
        longest, shortest = half + gap, half - gap
        if not (shortest > 0 and longest >= elongation * elongation * shortest):
            continue
        # the long axis: an eigenvector of [[a, b], [b, c]] for ``longest``, from the row that
        # cannot vanish (elongated, so not isotropic)
        vx, vy = (longest - c, b) if a >= c else (b, longest - a)
        count += 1
        split[k] = count
        line[k, 0], line[k, 1], line[k, 2], line[k, 3] = cx, cy, vx, vy
    if count == K:
        return labels, contact_reach(labels, K, near)
    halved = labels.copy()
    for i in range(m):
        k = labels[i]
        if k > 0 and split[k] > 0:
            if (positions[i, 0] - line[k, 0]) * line[k, 2] + (positions[i, 1] - line[k, 1]) * line[k, 3] > 0:
                halved[i] = split[k]
    return halved, contact_reach(halved, count, near)


@numba.njit(cache=True, nogil=True)
def fit_view(b, labels, near, source, cells):
    """The contact fit's view of a frame: its sub-cell columns on the sensors near the contacts.

    Parameters
    ----------
    b : (m,) ndarray
        Sensor stress, pascals.
    labels : (m,) ndarray of int
        Contact 1..K of each node, 0 outside every contact.
    near : (m, K) ndarray of bool
        The sensors near each contact.
    source : (3 c m, m) ndarray
        The stress matrix's columns as rows, ``c`` sub-cells per node (sub-cell
        ``q`` of node ``j`` along x is row ``q m + j``; along y and z the same
        a ``c m`` further each).
    cells : int
        ``c``.

    Returns
    -------
    stress : (R,) ndarray
        ``b`` on the rows.
    fit : (3n, R) ndarray
        The columns along x, then y, then z, each on the rows, in one pass.
    column_contact, column_node, column_id : (n,) ndarray of int
        Contact 0..K-1, node and sub-cell id (``q m + node``) of each column.
    row_contact : (R, K) ndarray of bool
    """
    m, K = near.shape
    rows = np.empty(m, np.int64)
    R = 0
    for i in range(m):
        for c in range(K):
            if near[i, c]:
                rows[R] = i
                R += 1
                break
    index = np.flatnonzero(labels)
    n = cells * index.size
    column_id = np.empty(n, np.int64)
    column_node = np.empty(n, np.int64)
    column_contact = np.empty(n, np.int64)
    for q in range(cells):
        for i in range(index.size):
            column_id[q * index.size + i] = q * m + index[i]
            column_node[q * index.size + i] = index[i]
            column_contact[q * index.size + i] = labels[index[i]] - 1
    fit = np.empty((3 * n, R))
    for axis in range(3):
        for i in range(n):
            column = source[axis * cells * m + column_id[i]]
            for r in range(R):
                fit[axis * n + i, r] = column[rows[r]]
    stress = np.empty(R)
    row_contact = np.empty((R, K), np.bool_)
    for r in range(R):
        stress[r] = b[rows[r]]
        row_contact[r] = near[rows[r]]
    return stress, fit, column_contact, column_node, column_id, row_contact


@numba.njit(cache=True, nogil=True)
def template_misfit(matrix, labels, shear, g, misfit):
    """A friction-shaped template load, and what it leaves of the data.

    The template is ``Fz = g``, ``(Fx, Fy) = s_k g`` on the nodes of contact
    ``k`` and nothing elsewhere. ``C y`` reads only the columns it loads, in
    place: on one contact of a 16x16 skin about a seventh of them, without the
    copy that indexing them in numpy makes.

    Parameters
    ----------
    matrix : (3m, m) ndarray
        Stress matrix stored by column (one row of ``matrix`` per force column).
    labels : (m,) ndarray of int
        Contact 1..K of each node, 0 outside every contact.
    shear : (K, 2) ndarray
        ``s_k = mu_k (cos theta_k, sin theta_k)`` of every contact.
    g : (m,) ndarray
        Normal force of each node, newtons.
    misfit : (m,) ndarray
        The sensor stress ``b`` on entry (pascals), ``b - C y`` on return.
        Always a fresh writable copy: a frame read from a recording is
        read-only, and numba would compile this function again for it.

    Returns
    -------
    template : (3m,) ndarray
        ``y`` as ``[Fx; Fy; Fz]``, newtons.
    """
    m = g.shape[0]
    template = np.zeros(3 * m)
    for j in range(m):
        # (the solver's g is zero outside the contacts; label 0 must not read shear[-1])
        if g[j] != 0.0 and labels[j] > 0:
            sx, sy = shear[labels[j] - 1, 0], shear[labels[j] - 1, 1]
            template[j], template[m + j], template[2 * m + j] = sx * g[j], sy * g[j], g[j]
            _axpy(-template[j], matrix[j], misfit)
            _axpy(-template[m + j], matrix[m + j], misfit)
            _axpy(-g[j], matrix[2 * m + j], misfit)
    return template


@numba.njit(cache=True, nogil=True)
def contact_stress(xt, yt, zt, contact, shear, g, contacts):
    """The stress each contact's fitted template load explains on the fit's sensors.

    Parameters
    ----------
    xt, yt, zt : (n, R) ndarray
        Stress per newton of each column along x, y, z on the rows.
    contact : (n,) ndarray of int
        Contact of each column.
    shear : (K, 2) ndarray
        Each contact's pair ``s_k``.
    g : (n,) ndarray
        Normal force of each column, newtons.
    contacts : int
        ``K``.

    Returns
    -------
    (K, R) ndarray
        Pascals.
    """
    n, rows = zt.shape
    out = np.zeros((contacts, rows))
    for j in range(n):
        if g[j] > 0:
            c = contact[j]
            sx, sy = g[j] * shear[c, 0], g[j] * shear[c, 1]
            for r in range(rows):
                out[c, r] += g[j] * zt[j, r] + sx * xt[j, r] + sy * yt[j, r]
    return out


@numba.njit(cache=True, nogil=True)
def load_patches(xt, yt, zt, contact, node, shear, g, indptr, indices):
    """The patches of a fitted load and the stress each explains (the contact fit's load decision).

    A patch is a connected piece of one contact's positive load: nodes with load,
    linked when neighbours (``indptr``, ``indices``: the CSR rows of the
    neighbour matrix over the skin's m nodes) and of the same contact.

    Returns
    -------
    column_patch : (n,) ndarray of int
        Patch of each column, -1 where ``g`` is 0.
    patch_contact : (P,) ndarray of int
    size : (P,) ndarray of int
        Positive columns of each patch.
    explained : (P, R) ndarray
        Stress on the rows of each patch's load, ``A_P g_P``.
    """
    n, rows = zt.shape
    m = indptr.size - 1
    node_contact = np.full(m, -1, np.int64)
    for j in range(n):
        if g[j] > 0:
            node_contact[node[j]] = contact[j]
    node_patch = np.empty(m, np.int64)
    patches = _components(node_contact, indptr, indices, node_patch)
    node_patch -= 1
    patch_contact = np.empty(patches, np.int64)
    for i in range(m):
        if node_patch[i] >= 0:
            patch_contact[node_patch[i]] = node_contact[i]
    column_patch = np.full(n, -1, np.int64)
    size = np.zeros(patches, np.int64)
    explained = np.zeros((patches, rows))
    for j in range(n):
        if g[j] > 0:
            k = node_patch[node[j]]
            column_patch[j] = k
            size[k] += 1
            sx, sy = g[j] * shear[contact[j], 0], g[j] * shear[contact[j], 1]
            for r in range(rows):
                explained[k, r] += g[j] * zt[j, r] + sx * xt[j, r] + sy * yt[j, r]
    return column_patch, patch_contact, size, explained


# -- the decisions after the search: shear evidence and load evidence ------------------------

# np.nan_to_num's stand-ins for infinities (the decisions' statistics were defined with it)
_LARGEST = np.finfo(np.float64).max


@numba.njit(cache=True, nogil=True)
def _finite(value):
    # np.nan_to_num(value, nan=0.0) of one number
    if math.isnan(value):
        return 0.0
    if math.isinf(value):
        return _LARGEST if value > 0 else -_LARGEST
    return value


@numba.njit(cache=True, nogil=True)
def near_sums(values, row_contact):
    """``values @ row_contact``: the sum of ``values`` (R,) over each contact's rows (R, K) of bool."""
    rows, K = row_contact.shape
    out = np.zeros(K)
    for r in range(rows):
        for c in range(K):
            if row_contact[r, c]:
                out[c] += values[r]
    return out


@numba.njit(cache=True, nogil=True)
def misfit_variance(stress, residual, row_contact, column_contact, g, parameters, model_error, unknown):
    """The misfit variance near each contact (the contact fit's noise estimate).

    Its residual over its degrees of freedom (the sensors near it less its
    positive columns and ``parameters``), at least the model's own error
    ``(model_error * peak)^2``, ``peak`` the largest stress near it.

    Parameters
    ----------
    stress, residual : (R,) ndarray
        Pascals.
    row_contact : (R, K) ndarray of bool
    column_contact : (n,) ndarray of int
    g : (n,) ndarray
        The fitted profile, newtons.
    parameters : int
        Free shear parameters of each contact.
    model_error : float
    unknown : float
        The variance where no freedom is left; NaN: the model's error floor.

    Returns
    -------
    (K,) ndarray
        Pascals squared.
    """
    rows, K = row_contact.shape
    rho, count, peak = np.zeros(K), np.zeros(K), np.zeros(K)
    for r in range(rows):
        square, size = residual[r] * residual[r], abs(stress[r])
        for c in range(K):
            if row_contact[r, c]:
                rho[c] += square
                count[c] += 1
                peak[c] = max(peak[c], size)
    positive = np.zeros(K)
    for j in range(g.size):
        if g[j] > 0:
            positive[column_contact[j]] += 1
    variance = np.empty(K)
    for c in range(K):
        dof = count[c] - positive[c] - parameters
        floor = (model_error * peak[c]) ** 2
        if dof > 0:
            variance[c] = max(rho[c] / max(dof, 1.0), floor)
        else:
            variance[c] = floor if math.isnan(unknown) else unknown
    return variance


@numba.njit(cache=True, nogil=True)
def shear_evidence(stress, row_contact, gain, variance, parameters):
    """The F statistic of each contact's gain in ``|residual|^2`` near it from ``parameters`` shear
    parameters; a gain below 1e-10 of ``|b|^2`` there is no evidence (rounding: on exact template data
    the search gains up to 1e-31 of it, measured, or far below any noise).

    Returns
    -------
    (K,) ndarray
        ``inf`` where the variance is 0, given as the largest float (as ``np.nan_to_num``).
    """
    scale = near_sums(stress * stress, row_contact)
    K = gain.size
    evidence = np.empty(K)
    for c in range(K):
        kept = gain[c] if gain[c] > 1e-10 * scale[c] else 0.0
        evidence[c] = _finite(kept / parameters / variance[c] if variance[c] > 0 else np.inf)
    return evidence


@numba.njit(cache=True, nogil=True, error_model="numpy")  # 0 / 0 is NaN, as in numpy
def load_decision(xt, yt, zt, contact, node, shear, g, residual, indptr, indices, stress, row_contact,
                  model_error, min_evidence):
    """The contact fit's load decision: patches of fitted load the data cannot tell from noise are dropped.

    Patch ``P`` (:func:`load_patches`) explains ``A_P g_P``; its evidence is
    ``L_P = (chi2_P - n_P) / sqrt(2 n_P)``, ``chi2_P = |A_P g_P|^2 / variance``
    (:func:`misfit_variance` of its contact without shear parameters, the
    model's floor where no freedom is left), ``n_P`` its positive columns.
    Patches below ``min_evidence`` are noise.

    Returns
    -------
    g : (n,) ndarray
        The profile without the noise patches (a new array).
    residual : (R,) ndarray
        ``A g - b`` without them (a new array).
    load_evidence : (K,) ndarray
        Each contact's strongest patch kept, 0 without one.
    """
    column_patch, patch_contact, size, explained = load_patches(xt, yt, zt, contact, node, shear, g,
                                                                indptr, indices)
    variance = misfit_variance(stress, residual, row_contact, contact, g, 0, model_error, np.nan)
    patches, rows = explained.shape
    K = row_contact.shape[1]
    noise = np.zeros(patches, np.bool_)
    removed = np.zeros(rows)
    load_evidence = np.zeros(K)
    for q in range(patches):
        square = 0.0
        for r in range(rows):
            square += explained[q, r] * explained[q, r]
        chi2 = _finite(square / variance[patch_contact[q]])
        evidence = (chi2 - size[q]) / math.sqrt(2 * size[q])
        if evidence < min_evidence:
            noise[q] = True
            for r in range(rows):
                removed[r] += explained[q, r]
        else:
            load_evidence[patch_contact[q]] = max(load_evidence[patch_contact[q]], evidence)
    kept = g.copy()
    for j in range(g.size):
        if column_patch[j] >= 0 and noise[column_patch[j]]:
            kept[j] = 0.0
    return kept, residual - removed, load_evidence


# -- the Gauss-Newton search over the shear pairs ----------------------------------------------

BOTH, RATIO, DIRECTION = 0, 1, 2    # which parameters are free


@numba.njit(cache=True, nogil=True)
def pairs_of(p, mode, direction, ratio, max_ratio, s):
    # the pairs s (K, 2) of the free parameters p (K, k)
    for c in range(p.shape[0]):
        if mode == BOTH:  # p = s, its ratio clipped to max_ratio
            mu = math.hypot(p[c, 0], p[c, 1])
            scale = min(1.0, max_ratio / max(mu, 1e-300))
            s[c, 0], s[c, 1] = p[c, 0] * scale, p[c, 1] * scale
        elif mode == RATIO:  # p = mu along the given direction
            mu = min(max(p[c, 0], 0.0), max_ratio)
            s[c, 0], s[c, 1] = mu * direction[0], mu * direction[1]
        else:  # p = theta at the given ratio
            s[c, 0], s[c, 1] = ratio * math.cos(p[c, 0]), ratio * math.sin(p[c, 0])


@numba.njit(cache=True, nogil=True)
def _jacobian(p, mode, direction, ratio, jacobian):
    # ds/dp (K, 2, k)
    for c in range(p.shape[0]):
        if mode == BOTH:
            jacobian[c, 0, 0], jacobian[c, 0, 1] = 1.0, 0.0
            jacobian[c, 1, 0], jacobian[c, 1, 1] = 0.0, 1.0
        elif mode == RATIO:
            jacobian[c, 0, 0], jacobian[c, 1, 0] = direction[0], direction[1]
        else:
            jacobian[c, 0, 0], jacobian[c, 1, 0] = -ratio * math.sin(p[c, 0]), ratio * math.cos(p[c, 0])


@numba.njit(cache=True, nogil=True)
def fit_at(xt, yt, zt, contact, b, s, free, g, residual, factor, index, columns):
    # the NNLS profile at the pairs s, warm from the set ``free``; returns the set changes
    # (-1: stopped short of the optimum, see lawson_hanson), the set size and |residual|^2
    n, rows = zt.shape
    for j in range(n):
        sx, sy = s[contact[j], 0], s[contact[j], 1]
        for r in range(rows):
            columns[j, r] = zt[j, r] + sx * xt[j, r] + sy * yt[j, r]
    steps, k = lawson_hanson(columns, b, free, 3 * n + 10, g, factor, index)
    for r in range(rows):
        residual[r] = -b[r]
    for i in range(k):
        _axpy(g[index[i]], columns[index[i]], residual)
    return steps, k, residual @ residual


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _step(xt, yt, contact, g, residual, columns, factor, index, k, jacobian, kp):
    # Gauss-Newton step of the linearized problem in (g on its set, dp) together, with g
    # eliminated through the set's Cholesky factor: with J = d(A g)/dp and W = A_S^T J,
    # (J^T J - W^T G^-1 W) dp = -J^T r, G = A_S^T A_S = L L^T. Loops, not BLAS: its several
    # hundred inner products of 200 are too short for a library call each (3.2x faster alone).
    K = jacobian.shape[0]
    q = K * kp
    rows = residual.shape[0]
    sx = np.zeros((K, rows))
    sy = np.zeros((K, rows))
    for j in range(g.shape[0]):
        if g[j] > 0:
            _axpy(g[j], xt[j], sx[contact[j]])
            _axpy(g[j], yt[j], sy[contact[j]])
    J = np.empty((q, rows))
    for c in range(K):
        for l in range(kp):
            a, b = jacobian[c, 0, l], jacobian[c, 1, l]
            for r in range(rows):
                J[c * kp + l, r] = sx[c, r] * a + sy[c, r] * b
    W = np.empty((q, k))
    V = np.empty((q, k))
    for i in range(k):
        column = columns[index[i]]
        for a in range(q):
            W[a, i] = _dot(J[a], column)
    for a in range(q):
        _solve(factor, k, W[a], V[a])
    schur = np.empty((q, q))
    rhs = np.empty(q)
    for a in range(q):
        rhs[a] = -_dot(J[a], residual)
        for b in range(q):
            schur[a, b] = _dot(J[a], J[b]) - _dot(W[a], V[b])
    try:
        return np.linalg.solve(schur, rhs)
    except Exception:  # a contact whose columns carry no load: no curvature along its pair
        return np.linalg.lstsq(schur, rhs)[0]


@numba.njit(cache=True, nogil=True)
def gauss_newton(xt, yt, zt, contact, b, mode, direction, ratio, max_ratio, p, guess, max_iterations,
                 tolerance):
    # Gauss-Newton with step halving on the free parameters, the profile eliminated (variable
    # projection); the first NNLS starts from the set ``guess``, each trial's from the current
    # positive set. Returns the parameters, profile and residual found, the profile and
    # residual at the start, and whether every fit reached its optimum (the step assumes it:
    # a fit stopped short ends the search at the last optimal one, or is not a trial).
    n, rows = zt.shape
    K, kp = p.shape
    s = np.empty((K, 2))
    jacobian = np.zeros((K, 2, kp))
    columns, trial_columns = np.empty((n, rows)), np.empty((n, rows))
    factor, index = workspace(zt)
    trial_factor, trial_index = workspace(zt)
    free, trial_free = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
    g, trial_g = np.zeros(n), np.zeros(n)
    residual, trial_residual = np.empty(rows), np.empty(rows)
    p = p.copy()
    free[:] = guess
    pairs_of(p, mode, direction, ratio, max_ratio, s)
    steps, k, rho = fit_at(xt, yt, zt, contact, b, s, free, g, residual, factor, index, columns)
    optimal = steps >= 0
    start_g, start_residual = g.copy(), residual.copy()
    for _ in range(max_iterations):
        if k == 0 or not optimal:
            break
        _jacobian(p, mode, direction, ratio, jacobian)
        step = _step(xt, yt, contact, g, residual, columns, factor, index, k, jacobian, kp).reshape(K, kp)
        accepted = False
        for _halving in range(6):
            trial = p + step
            pairs_of(trial, mode, direction, ratio, max_ratio, s)
            for j in range(n):
                trial_free[j] = g[j] > 0
            trial_steps, trial_k, trial_rho = fit_at(xt, yt, zt, contact, b, s, trial_free, trial_g,
                                                     trial_residual, trial_factor, trial_index, trial_columns)
            if trial_steps >= 0 and trial_rho < rho:
                accepted = True
                break
            step = step / 2
        if not accepted:
            break
        converged = np.max(np.abs(step)) < tolerance or rho - trial_rho < tolerance * 0.1 * rho
        p = trial
        k, rho = trial_k, trial_rho
        g, trial_g = trial_g, g
        residual, trial_residual = trial_residual, residual
        factor, trial_factor = trial_factor, factor
        index, trial_index = trial_index, index
        columns, trial_columns = trial_columns, columns
        if converged:
            break
    return p, g, residual, start_g, start_residual, optimal
