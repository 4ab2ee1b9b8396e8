"""Compiled kernels of the reflex controllers' per-block arithmetic (optional: Numba).

A reflex controller evaluates its laws once per block of a few physics steps, on arrays
of a few dozen numbers, where NumPy spends its time in the overhead of each small
operation rather than in the arithmetic. These kernels do the elementwise parts of a
block in one compiled call each.

They change no result: each does, element by element and in the same order, the IEEE
operations of the NumPy code it stands in for (no fused multiply-add, no reassociation:
Numba's defaults), and ``kernels_test.py`` checks them equal bit for bit, alone and
over whole walks and trips. What would not be the same stays NumPy's: its transcendental
functions (``tanh``, ``exp``, ``log``, ``power``, ``arctan2``: SIMD implementations that
round differently from a compiled libm on some CPUs) and its matrix products (BLAS).

Where NumPy's own code would differ from a compiled one, the kernels can still call it:
``numpy_loops`` finds the inner loops NumPy itself runs for those functions (a ufunc's
loop for float64, read from the ufunc object; ``matmul``'s calls OpenBLAS as
``np.matmul`` does) and the kernels call them with the shapes and strides NumPy would, so
that a whole block of the network is one compiled call. They are used only after a check
at load that each gives NumPy's bits on test arrays of the shapes the controllers use;
where the check fails (another NumPy's layout), the calls above stay NumPy's.

The same holds across blocks: ``net_run`` and ``gh_run`` run several whole blocks, each
the block's update, its steps (``rollout_block``: ``mj_step`` and ``mj_getState`` called
by address on the model and data, as ``mujoco.rollout`` takes them) and its sensing, in
one call, for ``ReflexController.run_blocks`` and ``GH2010Controller.run_blocks`` when
``sim.run`` hands them ``sim.NativePhysics``.

Two kernels serve the fits rather than a controller: ``batch_z`` and ``batch_dh``, the
motor paths of ``Network.forward`` and ``Network.gradient_z`` over a whole training set
(DAgger's training, the identification), each sum in einsum's order and each path's
share added in the paths' order, so that the fits give the NumPy code's numbers
(``controller_test.py``).

Numba is the optional extra ``fast`` (``pip install -e ".[fast]"``, in ``dev`` too).
Without it, or with ``STUMBLE_KERNELS=numpy`` in the environment, the NumPy code runs;
the numbers are the same either way, only the time differs (``benchmarks/bench_reflex.py``).
The first use in a process compiles the kernels (a few seconds, the first time on a
machine) or loads them from Numba's cache (about 0.4 s with Numba's import and the check
of NumPy's loops). Kernels reach each other as module globals, never as closure cells:
Numba keys its cache by the cells' pickled values, and a compiled function pickles
differently in every process, so a kernel closing over another would compile anew in
each.
"""

from __future__ import annotations

import math
import os

import numpy as np

ENV = "STUMBLE_KERNELS"  # "numpy": the reference code even where Numba is installed


def _load():
    """The compiled kernels, or None (no Numba, or ``STUMBLE_KERNELS=numpy``)."""
    if os.environ.get(ENV, "").strip().lower() == "numpy":
        return None
    try:
        import numba
    except ImportError:
        return None
    try:
        return _compiled(numba)
    except Exception as e:  # e.g. no writable cache: the NumPy code runs
        import warnings

        warnings.warn(f"stumble: the compiled reflex kernels are off ({e}); the NumPy code "
                      "runs, with the same numbers", RuntimeWarning, stacklevel=2)
        return None


# NumPy's inner loops the kernels call (``numpy_loops``), by index
LOOPS = (("tanh", "d->d"), ("exp", "d->d"), ("log", "d->d"), ("power", "dd->d"),
         ("arctan2", "dd->d"), ("matmul", "dd->d"))
TANH, EXP, LOG, POWER, ARCTAN2, MATMUL = range(len(LOOPS))
_NPY_DOUBLE = 12  # NumPy's type number of float64


call_loop = None  # ``_loop_call.call_loop`` once the kernels are compiled (``_compiled``)


def _loop_address(ufunc, sig: str) -> int | None:
    """Address of the inner loop NumPy runs for ``ufunc`` on ``sig``, read from its
    ``PyUFuncObject`` (``functions[k]``; CPython's 16-byte object head, then four ints),
    or None where the object is not laid out so (its type count and the loop's type
    codes are checked) or the loop needs a data pointer."""
    import ctypes
    import sys

    if sys.implementation.name != "cpython" or sys.maxsize < 2**63 - 1:
        return None  # (an object's address and head as CPython's on 64 bits only)
    try:
        k = ufunc.types.index(sig)
        base, nargs = id(ufunc), ufunc.nargs
        if ctypes.c_int.from_address(base + 24).value != nargs:
            return None
        functions = ctypes.c_void_p.from_address(base + 32).value
        data = ctypes.c_void_p.from_address(base + 40).value
        if ctypes.c_int.from_address(base + 48).value != len(ufunc.types) or not functions:
            return None
        types = ctypes.c_void_p.from_address(base + 64).value
        codes = ctypes.string_at(types + k * nargs, nargs)
        if any(c != _NPY_DOUBLE for c in codes):
            return None
        if data and ctypes.c_void_p.from_address(data + 8 * k).value:
            return None
        return ctypes.c_void_p.from_address(functions + 8 * k).value
    except Exception:  # (any surprise: the NumPy calls stay)
        return None


def numpy_loops(kern: dict) -> np.ndarray | None:
    """``LOOPS``' addresses (int64) if each, called by the kernels, gives NumPy's bits on
    test arrays (contiguous, strided, a scalar exponent; the matrix products of the
    networks' sizes), else None."""
    addr = [_loop_address(getattr(np, name), sig) for name, sig in LOOPS]
    if any(a is None for a in addr):
        return None
    loops = np.array(addr, dtype=np.int64)
    meta = np.zeros(16, dtype=np.int64)
    rng = np.random.default_rng(20261205)
    same = lambda a, b: a.shape == b.shape and np.array_equal(  # noqa: E731
        a.view(np.int64), b.view(np.int64))
    try:
        for n in (1, 7, 16, 33, 200, 1001):
            x = rng.normal(0.0, 3.0, n)
            y = rng.normal(0.0, 3.0, n)
            for i, ref in ((TANH, np.tanh(x)), (EXP, np.exp(x)),
                           (LOG, np.log(np.abs(x) + 1.0))):
                out = np.empty(n)
                src = np.abs(x) + 1.0 if i == LOG else x
                kern["loop1"](loops, i, meta, src, out)
                inplace = src.copy()  # (as the network runs tanh and exp)
                kern["loop1"](loops, i, meta, inplace, inplace)
                if not (same(out, ref) and same(inplace, ref)):
                    return None
            out = np.empty(n)
            kern["loop_pow"](loops, meta, np.abs(x), 0.6, out)
            if not same(out, np.power(np.abs(x), 0.6)):
                return None
            g = rng.normal(0.0, 1.0, (n, 7))
            out = np.empty(n)
            kern["loop_atan2_cols"](loops, meta, g, 0, 1, out)
            if not same(out, np.arctan2(g[:, 0], g[:, 1])):
                return None
            out = np.empty(n)
            kern["loop2"](loops, ARCTAN2, meta, x, y, out)
            if not same(out, np.arctan2(x, y)):
                return None
        for n, k, p in ((8, 60, 120), (4, 33, 7), (1, 50, 7), (12, 200, 21), (8, 7, 3)):
            x = rng.normal(0.0, 1.0, (n, 2, k))
            w = rng.normal(0.0, 1.0, (k, p))
            out, ref = np.empty((n, 2, p)), np.empty((n, 2, p))
            kern["loop_matmul"](loops, meta, x, w, out)
            np.matmul(x, w, out=ref)
            if not same(out, ref):
                return None
    except Exception:
        return None
    return loops


def _compiled(numba) -> dict:
    """Every kernel, compiled (lazily, cached by Numba) by ``numba``."""
    jit = numba.njit(cache=True, error_model="numpy", nogil=True)
    # module globals, not closure cells: Numba keys its cache by the closure cells'
    # pickled values, which differ from process to process for compiled functions
    global call_loop, loop1, loop_binary, loop2, loop_pow, loop_atan2_cols, loop_matmul
    global balance_cols, net_pre, net_push, net_drive, net_out, ring_take, store_rows
    global net_observe, bal_store, place_pre, place_alpha, place_drive_add, iir2, ib_push
    global store_take, bal_out, observe_all, observe_store, gh_channels, gh_place_in
    global place_offsets, net_update, net_sense, gh_update, gh_observe, gh_sense, gh_push
    global gh_laws, gh_features, gh_select, gh_lean, gh_place, gh_touch, clip_plan
    global call_step, call_get_state, net_run, resp_drive, resp_add, resp_onsets
    global gto_steps, rollout_block, block_ends_run, gh_run, batch_z, batch_dh, path_index
    from stumble.control.reflex._loop_call import call_get_state as _get
    from stumble.control.reflex._loop_call import call_loop as _call
    from stumble.control.reflex._loop_call import call_step as _step

    call_loop, call_step, call_get_state = _call, _step, _get

    @jit
    def loop1(loops, i, meta, x, out):
        """NumPy's loop ``i`` of one argument over contiguous ``x`` into ``out`` (as NumPy
        runs it on a contiguous array of any shape: one loop of ``x.size``)."""
        m = meta.ctypes.data
        meta[0] = x.ctypes.data
        meta[1] = out.ctypes.data
        meta[2] = x.size
        meta[3] = 8
        meta[4] = 8
        call_loop(loops[i], m, m + 16, m + 24)

    @jit
    def loop_binary(fn, meta, pa, sa, pb, sb, po, n):
        """The NumPy loop at ``fn`` of two arguments at addresses ``pa``, ``pb`` (strides
        ``sa``, ``sb`` bytes) into a contiguous ``po``, ``n`` elements."""
        m = meta.ctypes.data
        meta[0] = pa
        meta[1] = pb
        meta[2] = po
        meta[3] = n
        meta[4] = sa
        meta[5] = sb
        meta[6] = 8
        call_loop(fn, m, m + 24, m + 32)

    @jit
    def loop2(loops, i, meta, a, b, out):
        """NumPy's loop ``i`` of two contiguous arguments of one shape into ``out``."""
        loop_binary(loops[i], meta, a.ctypes.data, 8, b.ctypes.data, 8, out.ctypes.data,
                    a.size)

    @jit
    def loop_pow(loops, meta, x, e, out):
        """``np.power(x, e, out=out)``, ``x`` contiguous and ``e`` a scalar (NumPy's
        loop with the exponent's stride 0; the exponent in ``meta[15]``)."""
        ev = meta[15:16].view(np.float64)
        ev[0] = e
        loop_binary(loops[POWER], meta, x.ctypes.data, 8, ev.ctypes.data, 0,
                    out.ctypes.data, x.size)

    @jit
    def loop_atan2_cols(loops, meta, g, i, j, out):
        """``np.arctan2(g[:, i], g[:, j])`` of a C-contiguous (n, c) ``g`` into ``out``
        (n,) (NumPy's loop over the two strided columns)."""
        loop_binary(loops[ARCTAN2], meta, g.ctypes.data + 8 * i, g.strides[0],
                    g.ctypes.data + 8 * j, g.strides[0], out.ctypes.data, g.shape[0])

    @jit
    def loop_matmul(loops, meta, x, w, out):
        """``np.matmul(x, w, out=out)`` of (n, a, k) by (k, p) into (n, a, p): NumPy's
        gufunc loop over the n matrices (``w``'s outer stride 0)."""
        m = meta.ctypes.data
        meta[0] = x.ctypes.data
        meta[1] = w.ctypes.data
        meta[2] = out.ctypes.data
        meta[3] = x.shape[0]
        meta[4] = x.shape[1]
        meta[5] = x.shape[2]
        meta[6] = w.shape[1]
        meta[7] = x.strides[0]
        meta[8] = 0
        meta[9] = out.strides[0]
        meta[10] = x.strides[1]
        meta[11] = x.strides[2]
        meta[12] = w.strides[0]
        meta[13] = w.strides[1]
        meta[14] = out.strides[1]
        meta[15] = out.strides[2]
        call_loop(loops[MATMUL], m, m + 24, m + 56)

    @jit
    def balance_cols(sensed, kp, kd, ref, rectified, k_lean, swing_below_n, k_bw,
                     weight_n, out):
        """``TrunkBalance.drive_cols`` into ``out`` (n, 2, 3)."""
        for i in range(sensed.shape[0]):
            lean = sensed[i, 0] - ref
            g = kp * lean + kd * sensed[i, 1]
            f0 = sensed[i, 2]
            f1 = sensed[i, 3]
            total = f0 + f1
            if total > 0.0:
                s0 = f0 / total
                s1 = f1 / total
            else:
                s0 = 0.5
                s1 = 0.5
            if rectified:
                ge = g if (g >= 0.0 or g != g) else 0.0
                gf = -g if (-g >= 0.0 or g != g) else 0.0
                out[i, 0, 0] = ge * s0
                out[i, 0, 1] = ge * s0
                out[i, 0, 2] = gf * s0
                out[i, 1, 0] = ge * s1
                out[i, 1, 1] = ge * s1
                out[i, 1, 2] = gf * s1
            else:
                out[i, 0, 0] = g * s0
                out[i, 0, 1] = g * s0
                out[i, 0, 2] = -(g * s0)
                out[i, 1, 0] = g * s1
                out[i, 1, 1] = g * s1
                out[i, 1, 2] = -(g * s1)
            if k_lean != 0.0:
                kl = k_lean * lean
                out[i, 0, 2] += (1.0 if f0 < swing_below_n else 0.0) * kl
                out[i, 1, 2] += (1.0 if f1 < swing_below_n else 0.0) * kl
            if k_bw != 0.0:
                on0 = f0 > swing_below_n
                on1 = f1 > swing_below_n
                x0 = sensed[i, 4]
                x1 = sensed[i, 5]
                r0 = 1.0 if (on0 and on1 and x0 < x1) else 0.0
                r1 = 1.0 if (on1 and on0 and x1 < x0) else 0.0
                b0 = k_bw * f1 / weight_n * r0
                b1 = k_bw * f0 / weight_n * r1
                out[i, 0, 0] -= b0
                out[i, 1, 0] -= b1
                out[i, 0, 2] += b0
                out[i, 1, 2] += b1

    @jit
    def net_pre(sensed, k_mm, l_ref, ib_force, d, v, absv, fin):
        """The receptors' first step (``ReflexController._rates``) for ticks of ``sensed``
        (n, 3, m): fibre stretch ``d`` and its rate ``v`` (mm, mm/s), ``|v|``, and the
        tendon organ's ``max(F, 0)/ib_force + 1`` (F pulling positive), each (n, m)."""
        for i in range(sensed.shape[0]):
            for c in range(sensed.shape[2]):
                d[i, c] = k_mm[c] * (sensed[i, 0, c] - l_ref[c])
                vc = k_mm[c] * sensed[i, 1, c]
                v[i, c] = vc
                absv[i, c] = abs(vc)
                f = -sensed[i, 2, c]
                f = f if (f >= 0.0 or f != f) else 0.0
                fin[i, c] = f / ib_force + 1.0

    @jit
    def net_push(d, v, p, ib, loads, weight_n, contact, mean, inv_std, buf, first, gains):
        """The receptor rates of ticks first, first+1, … (Ia, II, Ib per muscle, then the
        load), each standardised, into the ring buffer ``buf`` (slot, 2·n_signals);
        ``gains``: Ia's velocity gain, stretch gain and base, II's base and stretch gain
        (``receptors``; arguments, not constants, so that Numba's cache cannot keep old
        ones)."""
        ia_gain, ia_stretch, ia_base, ii_base, ii_stretch = gains
        nm2 = d.shape[1]
        nm = nm2 // 2
        n_sig = buf.shape[1] // 2
        size = buf.shape[0]
        for i in range(d.shape[0]):
            row = (first + i) % size
            for s in range(2):
                base = s * n_sig
                for j in range(nm):
                    c = s * nm + j
                    dd = d[i, c]
                    ia = ia_gain * math.copysign(p[i, c], v[i, c]) + ia_stretch * dd + ia_base
                    ia = ia if (ia >= 0.0 or ia != ia) else 0.0
                    ii = ii_base + ii_stretch * dd
                    ii = ii if (ii >= 0.0 or ii != ii) else 0.0
                    buf[row, base + 3 * j] = (ia - mean[3 * j]) * inv_std[3 * j]
                    buf[row, base + 3 * j + 1] = (ii - mean[3 * j + 1]) * inv_std[3 * j + 1]
                    buf[row, base + 3 * j + 2] = (ib[i, c] - mean[3 * j + 2]) * inv_std[3 * j + 2]
                if contact:
                    q = 3 * nm
                    buf[row, base + q] = (loads[i, s] / weight_n - mean[q]) * inv_std[q]

    @jit
    def net_drive(t, c):
        """The motor neurons' negated drive, −(t + c), in place in ``t`` (n, 2, m)."""
        for i in range(t.shape[0]):
            for s in range(2):
                for j in range(t.shape[2]):
                    t[i, s, j] = -(t[i, s, j] + c[j])

    @jit
    def net_out(e, bal, cols, exc, ctrl, plan, plan_rows, first, held):
        """Motor neurons' excitation ``1/(1 + e)`` (n, 2, m) from ``e`` = exp(−drive), the
        trunk balance ``bal`` (n, 2, 3) added on ``cols`` (when ``bal`` has rows), and
        the controls clipped to 0.01-1 (n, 2·m); when ``plan`` has rows, row ``i`` is
        ``held`` (the controls now) with the muscles' columns from ``first`` set to the
        controls' row ``plan_rows[i]`` (the tick that physics step holds)."""
        n, _two, m = e.shape
        for i in range(n):
            for s in range(2):
                for j in range(m):
                    exc[i, s, j] = 1.0 / (1.0 + e[i, s, j])
                if bal.shape[0]:
                    for c in range(3):
                        exc[i, s, cols[c]] += bal[i, s, c]
                for j in range(m):
                    u = exc[i, s, j]
                    u = u if (u >= 0.01 or u != u) else 0.01
                    ctrl[i, s * m + j] = u if (u <= 1.0 or u != u) else 1.0
        if plan.shape[0]:
            for i in range(plan.shape[0]):
                for q in range(plan.shape[1]):
                    plan[i, q] = held[q]
                for q in range(2 * m):
                    plan[i, first + q] = ctrl[plan_rows[i], q]

    @jit
    def ring_take(buf, first, lag, off, row, size, out):
        """``out`` (n, 2, L): what ticks first … first+n−1 read of a flat ring buffer of
        ``size`` slots of ``row`` values, channel ``off[s, j]`` ``lag[j]`` ticks back."""
        for i in range(out.shape[0]):
            for j in range(out.shape[2]):
                base = ((first + i - lag[j]) % size) * row
                out[i, 0, j] = buf[base + off[0, j]]
                out[i, 1, j] = buf[base + off[1, j]]

    @jit
    def store_rows(h, buf, first):
        """Rows of ``h`` (n, 2, k) into the ring buffer ``buf`` (slots, 2·k) from slot
        ``first`` on (wrapping)."""
        k = h.shape[2]
        size = buf.shape[0]
        for i in range(h.shape[0]):
            r = (first + i) % size
            for s in range(2):
                for j in range(k):
                    buf[r, s * k + j] = h[i, s, j]

    @jit
    def net_observe(ticks, obs_cols, n_mus3, contact, sensed, loads, bal_cols, bal_g):
        """``ReflexController.observe``'s gathers: the muscles' lengths, velocities and
        forces into ``sensed`` (n, 3, m), the feet's loads into ``loads`` (n, 2), the
        trunk balance's columns ``bal_cols`` into ``bal_g`` (n, 7)."""
        m = n_mus3 // 3
        for i in range(ticks.shape[0]):
            for q in range(3):
                for c in range(m):
                    sensed[i, q, c] = ticks[i, obs_cols[q * m + c]]
            if contact:
                for s in range(obs_cols.shape[0] - n_mus3):
                    loads[i, s] = -ticks[i, obs_cols[n_mus3 + s]]
            for j in range(bal_cols.shape[0]):
                bal_g[i, j] = ticks[i, bal_cols[j]]

    @jit
    def bal_store(g, lean, buf, first):
        """``TrunkBalance.sense`` from its gathered columns ``g`` (n, 7) and the lean,
        into the ring buffer ``buf`` from slot ``first`` on: lean, pitch rate, the feet's
        loads, the ankles' x."""
        size = buf.shape[0]
        for i in range(g.shape[0]):
            r = (first + i) % size
            buf[r, 0] = lean[i]
            buf[r, 1] = g[i, 2]
            buf[r, 2] = -g[i, 3]
            buf[r, 3] = -g[i, 4]
            buf[r, 4] = g[i, 5]
            buf[r, 5] = g[i, 6]

    @jit
    def place_pre(ticks, cols, d, buf, first):
        """``TrunkBalance.place_sense`` but its arctan2: from the sensor rows' columns
        ``cols`` (pelvis x, z, the ankles' x, their z, the COM's x and vx), each leg's
        pelvis-to-ankle x and z into ``d`` (2, n, 2) for the angle, and the COM ahead of
        each other ankle and its speed into ``buf``'s columns 2-4 from slot ``first``."""
        size = buf.shape[0]
        for i in range(ticks.shape[0]):
            r = (first + i) % size
            for s in range(2):
                d[0, i, s] = ticks[i, cols[2 + s]] - ticks[i, cols[0]]
                d[1, i, s] = ticks[i, cols[1]] - ticks[i, cols[4 + s]]
            buf[r, 2] = ticks[i, cols[6]] - ticks[i, cols[3]]
            buf[r, 3] = ticks[i, cols[6]] - ticks[i, cols[2]]
            buf[r, 4] = ticks[i, cols[7]]

    @jit
    def place_alpha(alpha, buf, first):
        """The legs' angles ``alpha`` (n, 2) into ``buf``'s columns 0-1 from ``first``."""
        size = buf.shape[0]
        for i in range(alpha.shape[0]):
            r = (first + i) % size
            buf[r, 0] = alpha[i, 0]
            buf[r, 1] = alpha[i, 1]

    @jit
    def place_drive_add(buf, rows, bal_buf, k_place, a0, cd, cv, swing_below_n, bal):
        """``bal += TrunkBalance.place_cols_drive(buf[rows], bal_buf[rows][:, 2:4])``: the
        placement's drive of GLU, HAMS and the flexor (n, 2, 3), added."""
        for i in range(rows.shape[0]):
            r = rows[i]
            for s in range(2):
                alpha = buf[r, s]
                e = k_place * (a0 + cd * buf[r, 2 + s] + cv * buf[r, 4] - alpha)
                on = 1.0 if (bal_buf[r, 2 + s] < swing_below_n and alpha > 0.0) else 0.0
                pe = e if (e >= 0.0 or e != e) else 0.0
                ne = -e if (-e >= 0.0 or e != e) else 0.0
                bal[i, s, 0] += on * ne
                bal[i, s, 1] += 0.0
                bal[i, s, 2] += on * pe

    @jit
    def iir2(b, a, x, z, y):
        """A second-order filter along axis 0 of ``x`` (n, channels) into ``y``, from and
        updating the state ``z`` (2, channels), in direct form II transposed with the
        operations in the order of SciPy's ``lfilter`` kernel (``a[0]`` is 1)."""
        for c in range(x.shape[1]):
            z0 = z[0, c]
            z1 = z[1, c]
            for k in range(x.shape[0]):
                xk = x[k, c]
                yk = z0 + b[0] * xk
                z0 = z1 + xk * b[1] - yk * a[1]
                z1 = xk * b[2] - yk * a[2]
                y[k, c] = yk
            z[0, c] = z0
            z[1, c] = z1

    @jit
    def ib_push(g, ib_gain, b, a, z, ib, d, v, p, loads, weight_n, contact, mean, inv_std,
                buf, first, gains, touches, touch_sig):
        """The receptors of ``ReflexController._next_block_compiled`` after NumPy's power
        and log: the tendon organs' ``ib_gain·log`` (in ``g``) filtered by ``iir2`` into
        ``ib``, then ``net_push``, then (``touch_sig`` ≥ 0) each foot's standardised
        touch into that signal of both sides."""
        for i in range(g.shape[0]):
            for c in range(g.shape[1]):
                g[i, c] = g[i, c] * ib_gain
        iir2(b, a, g, z, ib)
        net_push(d, v, p, ib, loads, weight_n, contact, mean, inv_std, buf, first, gains)
        if touch_sig >= 0:
            n_sig = buf.shape[1] // 2
            size = buf.shape[0]
            m, s = mean[touch_sig], inv_std[touch_sig]
            for i in range(g.shape[0]):
                row = (first + i) % size
                buf[row, touch_sig] = (touches[i, 0] - m) * s
                buf[row, n_sig + touch_sig] = (touches[i, 1] - m) * s

    @jit
    def store_take(h, hid2, h_first, hid, first, lag, off, row, size, out):
        """``store_rows(h, hid2, h_first)`` then ``ring_take(hid, first, …, out)``: the new
        interneurons stored, then what the motor neurons of ticks first… read (``hid2``
        is ``hid`` as (slots, row))."""
        store_rows(h, hid2, h_first)
        ring_take(hid, first, lag, off, row, size, out)

    @jit
    def bal_out(bal_buf, first, par, place_buf, rows, sensed, bal, e, cols, exc, ctrl, plan,
                plan_rows, act_first, held):
        """The trunk balance of the block's ticks (its ring rows from ``first``:
        ``balance_cols``, and with a ``place_buf`` of rows ``place_drive_add``) into
        ``bal``, then ``net_out``. ``par``: kp, kd, ref, rectified, k_lean, the stance
        load (N), k_bw, the body weight (N), k_place, a0, c_d, c_v."""
        size = bal_buf.shape[0]
        for i in range(rows.shape[0]):
            r = (first + i) % size
            rows[i] = r
            for j in range(bal_buf.shape[1]):
                sensed[i, j] = bal_buf[r, j]
        balance_cols(sensed, par[0], par[1], par[2], par[3] != 0.0, par[4], par[5], par[6],
                     par[7], bal)
        if place_buf.shape[0]:
            place_drive_add(place_buf, rows, bal_buf, par[8], par[9], par[10], par[11],
                            par[5], bal)
        net_out(e, bal, cols, exc, ctrl, plan, plan_rows, act_first, held)

    @jit
    def observe_all(rows, per_step, every, n, obs_cols, n_mus3, contact, sensed, loads,
                    bal_cols, bal_g, touch_cols, touches, place_cols, d, place_buf, first):
        """``ReflexController.observe``'s gathers from a block's sensor ``rows``, tick ``i``
        reading row ``i // per_step`` (``per_step`` > 1) or ``i·every``: ``net_observe``,
        each foot's touch ``min(row, 1)`` into ``touches`` (when ``touch_cols`` has
        columns) and (``place_buf`` with rows) ``place_pre``; whether a foot is touched."""
        any_touch = False
        for i in range(n):
            r = i // per_step if per_step > 1 else i * every
            x = rows[r]
            m = n_mus3 // 3
            for q in range(3):
                for c in range(m):
                    sensed[i, q, c] = x[obs_cols[q * m + c]]
            if contact:
                for s in range(obs_cols.shape[0] - n_mus3):
                    loads[i, s] = -x[obs_cols[n_mus3 + s]]
            for j in range(bal_cols.shape[0]):
                bal_g[i, j] = x[bal_cols[j]]
            for s in range(touch_cols.shape[0]):
                t = x[touch_cols[s]]
                t = t if (t <= 1.0 or t != t) else 1.0
                touches[i, s] = t
                if t > 0.0:
                    any_touch = True
            if place_buf.shape[0]:
                size = place_buf.shape[0]
                q = (first + i) % size
                for s in range(2):
                    d[0, i, s] = x[place_cols[2 + s]] - x[place_cols[0]]
                    d[1, i, s] = x[place_cols[1]] - x[place_cols[4 + s]]
                place_buf[q, 2] = x[place_cols[6]] - x[place_cols[3]]
                place_buf[q, 3] = x[place_cols[6]] - x[place_cols[2]]
                place_buf[q, 4] = x[place_cols[7]]
        return any_touch

    @jit
    def observe_store(g, lean, bal_buf, alpha, place_buf, first):
        """``bal_store`` (when ``bal_buf`` has rows) and ``place_alpha`` (when
        ``place_buf`` has rows) of a block's ticks."""
        if bal_buf.shape[0]:
            bal_store(g, lean, bal_buf, first)
        if place_buf.shape[0]:
            place_alpha(alpha, place_buf, first)

    @jit
    def gh_channels(rows, gather, scale, offset, v):
        """``GH2010Controller._channels``' affine map: ``v`` = rows[:, gather]·scale +
        offset (n, channels)."""
        for i in range(rows.shape[0]):
            for c in range(gather.shape[0]):
                v[i, c] = rows[i, gather[c]] * scale[c] + offset[c]

    @jit
    def gh_place_in(rows, cols, v, out, a, b):
        """``GH2010Controller._channels``' placement inputs: ``out`` (n, k + 5) gets the
        channels ``v`` but its last, then (after the caller's arctan2 of ``a`` over
        ``b``, the legs' angles) the COM ahead of each other ankle and its speed, from
        ``rows[:, cols]``: pelvis x, z, ankles' x, ankles' z, COM x, vx."""
        k = v.shape[1] - 1
        for i in range(rows.shape[0]):
            for c in range(k):
                out[i, c] = v[i, c]
        place_offsets(rows, cols, a, b, out, k + 2)

    @jit
    def place_offsets(rows, cols, a, b, out, c0):
        """The placement's inputs from ``rows[:, cols]`` (pelvis x, z, ankles' x, ankles'
        z, COM x, vx): each leg's pelvis-to-ankle x and z into ``a``, ``b`` (n, 2), and
        into ``out``'s columns ``c0``… the COM ahead of each other ankle and its speed."""
        for i in range(rows.shape[0]):
            r0 = rows[i, cols[0]]
            r1 = rows[i, cols[1]]
            a[i, 0] = rows[i, cols[2]] - r0
            a[i, 1] = rows[i, cols[3]] - r0
            b[i, 0] = r1 - rows[i, cols[4]]
            b[i, 1] = r1 - rows[i, cols[5]]
            r6 = rows[i, cols[6]]
            out[i, c0] = r6 - rows[i, cols[3]]
            out[i, c0 + 1] = r6 - rows[i, cols[2]]
            out[i, c0 + 2] = rows[i, cols[7]]

    @jit
    def net_update(loops, meta, rates, first, n_r, sensed, k_mm, l_ref, ib_force, sc,
                   ia_exp, ib_gain, gb, ga, gz, loads, weight_n, contact, mean, inv_std,
                   sig2d, gains, touches, touch_q, n_h, h_first, sig_buf, in_lag, in_off,
                   sig_row, n_buf, x, h, w, b, hid2d, hid_buf, k, c_lag, hid_off, hid_row,
                   hid, mv, t, c, bal_on, bal_first, bal_buf, bal_par, place_buf, bal_rows,
                   bal_sensed,
                   bal, bal_cols, exc, ctrl, plan, plan_rows, act_first, held, no_bal):
        """``ReflexController._next_block_compiled`` but its touch response, in one call:
        the same kernels, and NumPy's own loops where it calls NumPy (``loop1``...)."""
        if rates:  # the ticks sensed since the last block: receptors, pushed
            d, v, absv, fin = sc[0][:n_r], sc[1][:n_r], sc[2][:n_r], sc[3][:n_r]
            net_pre(sensed[:n_r], k_mm, l_ref, ib_force, d, v, absv, fin)
            p = sc[5][:n_r]
            loop_pow(loops, meta, absv, ia_exp, p)
            g = sc[6][:n_r]
            loop1(loops, LOG, meta, fin, g)
            ib_push(g, ib_gain, gb, ga, gz, sc[4][:n_r], d, v, p, loads[:n_r], weight_n,
                    contact, mean, inv_std, sig2d, first, gains, touches[:n_r], touch_q)
        if n_h > 0:  # the interneurons now sensed: tanh(x @ w + b), stored
            ring_take(sig_buf, h_first, in_lag, in_off, sig_row, n_buf, x)
            loop_matmul(loops, meta, x, w, h)
            for i in range(h.shape[0]):
                for s in range(2):
                    for j in range(h.shape[2]):
                        h[i, s, j] = h[i, s, j] + b[j]
            loop1(loops, TANH, meta, h, h)
            store_take(h, hid2d, h_first, hid_buf, k, c_lag, hid_off, hid_row, n_buf, hid)
        else:
            ring_take(hid_buf, k, c_lag, hid_off, hid_row, n_buf, hid)
        loop_matmul(loops, meta, hid, mv, t)
        net_drive(t, c)
        loop1(loops, EXP, meta, t, t)
        if bal_on:
            bal_out(bal_buf, bal_first, bal_par, place_buf, bal_rows, bal_sensed, bal, t,
                    bal_cols,
                    exc, ctrl, plan, plan_rows, act_first, held)
        else:
            net_out(t, no_bal, bal_cols, exc, ctrl, plan, plan_rows, act_first, held)

    @jit
    def net_sense(loops, meta, rows, per_step, every, n, obs_cols, n_mus3, contact, sensed,
                  loads, bal_cols, bal_g, touch_cols, touches, place_cols, d, place_buf,
                  first, lean, alpha, bal_buf, no_alpha):
        """``ReflexController._observe_compiled`` in one call (NumPy's arctan2 loop);
        whether a foot is touched."""
        touched = observe_all(rows, per_step, every, n, obs_cols, n_mus3, contact, sensed,
                              loads, bal_cols, bal_g, touch_cols, touches, place_cols, d,
                              place_buf, first)
        g = bal_g[:n]
        ln = lean[:n]
        if bal_buf.shape[0]:
            loop_atan2_cols(loops, meta, g, 0, 1, ln)
        al = no_alpha
        if place_buf.shape[0]:
            al = alpha[:n]
            loop2(loops, ARCTAN2, meta, d[0, :n], d[1, :n], al)
        observe_store(g, ln, bal_buf, al, place_buf, first)
        return touched

    @jit
    def gh_update(loops, meta, buf, idx, x, phi0, sign, off, low, knee_v0, has_ds, ds_load,
                  ds_x, stance_load, gate0, ungated, v, stance, w_st, a, b_st, w_sw, bb, b_sw,
                  ip, fp, u, scr, touch0, xt0, load0, xf0, hold, vas_after, by_foot, ahead_m,
                  w_sets, w_any, w_vas, cross, cross_hold, cross_ahead, w_cross, scr_since,
                  touched_was, ahead_was, armed, cross_since, was_on, mark, lo, plan,
                  act_first, held):
        """``GH2010Controller.update``'s compiled path in one call: the delayed taps
        (``DelayTaps.read``: ``buf``'s flat elements ``idx``) into ``x``, ``gh_features``,
        the two laws' matrix products (NumPy's loop), ``gh_laws``, ``gh_touch`` (``scr``)
        and ``clip_plan``; ``u`` (n, 2, nm) holds the excitations."""
        flat = buf.reshape(-1)
        for i in range(idx.shape[0]):
            for j in range(idx.shape[1]):
                x[i, j] = flat[idx[i, j]]
        gh_features(x, phi0, sign, off, low, knee_v0, has_ds, ds_load, ds_x, stance_load,
                    gate0, ungated, v, stance)
        loop_matmul(loops, meta, v, w_st, a)
        loop_matmul(loops, meta, v, w_sw, bb)
        gh_laws(stance, a, b_st, bb, b_sw, x, ip, fp, u)
        u2 = u.reshape(u.shape[0], -1)
        if scr:
            gh_touch(x, touch0, xt0, load0, xf0, stance_load, hold, vas_after, by_foot,
                     ahead_m, w_sets, w_any, w_vas, cross, cross_hold, cross_ahead, w_cross,
                     scr_since, touched_was, ahead_was, armed, cross_since, was_on, mark, u2)
        clip_plan(u2, lo, plan, act_first, held)

    @jit
    def gh_observe(loops, meta, rows, gather, scale, offset, v, place, cols, a, b, extra,
                   lean, alpha, buf, first):
        """``GH2010Controller.observe``'s compiled path in one call: ``gh_sense``, the
        lean's and the legs' arctan2 (NumPy's loop), ``gh_push``."""
        gh_sense(rows, gather, scale, offset, v, place, cols, a, b, extra)
        k = v.shape[1]
        loop_atan2_cols(loops, meta, v, k - 2, k - 1, lean)
        if place:
            loop2(loops, ARCTAN2, meta, a, b, alpha)
        gh_push(v, lean, place, alpha, extra, buf, first)

    @jit
    def gh_sense(rows, gather, scale, offset, v, place, cols, a, b, extra):
        """``gh_channels`` into ``v``; with ``place``, ``gh_place_in``'s inputs: the legs'
        x and z offsets ``a``, ``b`` (n, 2) for the caller's arctan2, and the COM ahead of
        each other ankle and its speed into ``extra`` (n, 3)."""
        gh_channels(rows, gather, scale, offset, v)
        if place:
            place_offsets(rows, cols, a, b, extra, 0)

    @jit
    def gh_push(v, lean, place, alpha, extra, buf, first):
        """A block's channels into the delay ring ``buf`` from slot ``first`` on: ``v``
        but its last two, the ``lean``, then (``place``) the legs' angles ``alpha`` and
        ``extra`` (``GH2010Controller._channels``' rows, pushed)."""
        k = v.shape[1] - 1
        size = buf.shape[0]
        for i in range(v.shape[0]):
            r = (first + i) % size
            for c in range(k - 1):
                buf[r, c] = v[i, c]
            buf[r, k - 1] = lean[i]
            if place:
                buf[r, k] = alpha[i, 0]
                buf[r, k + 1] = alpha[i, 1]
                buf[r, k + 2] = extra[i, 0]
                buf[r, k + 3] = extra[i, 1]
                buf[r, k + 4] = extra[i, 2]

    @jit
    def gh_laws(stance, a, b_st, b, b_sw, x, ip, fp, u):
        """``gh_select``, ``gh_lean`` and (``ip[7]``) ``gh_place`` into ``u``. ``ip``: the
        lean's and its rate's taps, the vestibular loads' and feet's first taps, GLU,
        HAMS, the flexor, placement on, its first tap, seed003 wiring, placement terms;
        ``fp``: lean_ref, kp, kd, k_lean, the stance load, k_bw, k_place, a0, c_d, c_v."""
        gh_select(stance, a, b_st, b, b_sw, u)
        gh_lean(x, ip[0], ip[1], ip[2], ip[3], fp[0], fp[1], fp[2], fp[3], fp[4],
                ip[9] != 0, fp[5], ip[4], ip[5], ip[6], u)
        if ip[7]:
            gh_place(x, ip[8], ip[2], fp[6], fp[7], fp[8], fp[9], ip[10] != 0, fp[4],
                     ip[6], ip[4], u)

    @jit
    def gh_features(x, phi0, sign, off, low, knee_v0, has_ds, ds_load0, ds_x0,
                    stance_load, gate0, ungated, v, stance):
        """``GH2010Controller._excitations``' features ``v`` (n, 2, K) and each muscle's
        stance ``stance`` (n, 2, nm) from the block's taps ``x`` (n, taps); the column
        arguments are where each group of taps starts."""
        nm = stance.shape[2]
        for i in range(x.shape[0]):
            for leg in range(2):
                for f in range(10):
                    t = x[i, phi0 + leg * 10 + f] * sign[f]
                    t = t - off[f]
                    lo = low[f]
                    v[i, leg, f] = t if (t >= lo or t != t) else lo
                v[i, leg, 8] *= 1.0 if x[i, knee_v0 + leg] < 0.0 else 0.0
                if has_ds:
                    other = 1 - leg
                    la = x[i, ds_load0 + leg]
                    lb = x[i, ds_load0 + other]
                    on = (la > stance_load) and (lb > stance_load)
                    rear = on and x[i, ds_x0 + leg] < x[i, ds_x0 + other]
                    v[i, leg, 10] = lb * (1.0 if rear else 0.0)
                for j in range(nm):
                    stance[i, leg, j] = (x[i, gate0 + leg * nm + j] > stance_load) or ungated[j]

    @jit
    def gh_select(stance, a, b_st, b, b_sw, u):
        """The stance law's ``a + b_st`` where a muscle is in stance, else the swing
        law's ``b + b_sw`` (n, 2, nm)."""
        for i in range(u.shape[0]):
            for leg in range(2):
                for j in range(u.shape[2]):
                    if stance[i, leg, j]:
                        u[i, leg, j] = a[i, leg, j] + b_st[j]
                    else:
                        u[i, leg, j] = b[i, leg, j] + b_sw[j]

    @jit
    def gh_lean(x, i_lean, i_lean_v, load0, x0, lean_ref, kp, kd, k_lean, stance_load,
                seed003, k_bw, i_glu, i_hams, i_flex, u):
        """``GH2010Controller._add_vestibular``: the trunk-lean laws added to ``u``."""
        for i in range(x.shape[0]):
            lean = x[i, i_lean] - lean_ref
            g = kp * lean + kd * x[i, i_lean_v]
            l0 = x[i, load0]
            l1 = x[i, load0 + 1]
            total = l0 + l1
            if total > 0.0:
                sh0 = l0 / total
                sh1 = l1 / total
            else:
                sh0 = 0.5
                sh1 = 0.5
            ge = g if (g >= 0.0 or g != g) else 0.0
            gf = -g if (-g >= 0.0 or g != g) else 0.0
            kl = k_lean * lean
            for leg in range(2):
                sh = sh0 if leg == 0 else sh1
                ld = l0 if leg == 0 else l1
                ext = ge * sh
                flex = gf * sh + (1.0 if ld < stance_load else 0.0) * kl
                glu = ext
                if seed003:
                    lo = l1 if leg == 0 else l0
                    rear = ((not ld < stance_load) and (not lo < stance_load)
                            and x[i, x0 + leg] < x[i, x0 + 1 - leg])
                    bw = k_bw * lo * (1.0 if rear else 0.0)
                    glu = ext + bw * -1.0
                    flex = flex + bw
                u[i, leg, i_glu] += glu
                u[i, leg, i_hams] += ext
                u[i, leg, i_flex] += flex

    @jit
    def gh_place(x, pl0, load0, k_place, a0, cd, cv, with_terms, stance_load, i_flex,
                 i_glu, u):
        """``GH2010Controller._add_placement``: the swing-leg placement added to ``u``."""
        for i in range(x.shape[0]):
            for leg in range(2):
                alpha = x[i, pl0 + leg]
                if with_terms:
                    e = k_place * (a0 + cd * x[i, pl0 + 2 + leg] + cv * x[i, pl0 + 4]
                                   - alpha)
                else:
                    e = k_place * (a0 - alpha)
                on = 1.0 if (x[i, load0 + leg] < stance_load and alpha > 0.0) else 0.0
                ep = e if (e >= 0.0 or e != e) else 0.0
                en = -e if (-e >= 0.0 or e != e) else 0.0
                u[i, leg, i_flex] += on * ep
                u[i, leg, i_glu] += on * en

    @jit
    def gh_touch(x, touch0, xt0, load0, xf0, stance_load, hold, vas_after, by_foot,
                 ahead_m, w_sets, w_any, w_vas, cross, cross_hold, cross_ahead, w_cross,
                 scr_since, touched_was, ahead_was, armed, cross_since, was_on, mark, u):
        """``GH2010Controller._stumble`` (and ``_crossing``) added to ``u`` (n, 2·nm), its
        state carried in the arrays after ``w_cross`` (``mark`` of one element). Every
        output element gets at most two non-zero terms (a touched leg's own sets, the
        other leg's set): their sum is NumPy's einsum's in any order."""
        n = x.shape[0]
        nm = w_vas.shape[2]
        last0 = -1
        last1 = -1
        first0 = -1
        first1 = -1
        prev0 = touched_was[0]
        prev1 = touched_was[1]
        ahead0 = ahead_was[0]
        ahead1 = ahead_was[1]
        since0 = 0.0
        since1 = 0.0
        was0 = was_on[0]
        was1 = was_on[1]
        out = np.zeros((2, nm))
        for i in range(n):
            t0 = x[i, touch0] > 0.0
            t1 = x[i, touch0 + 1] > 0.0
            if t0:
                last0 = i
            if t1:
                last1 = i
            since0 = float(i - last0) if last0 >= 0 else scr_since[0] + 1.0 + float(i)
            since1 = float(i - last1) if last1 >= 0 else scr_since[1] + 1.0 + float(i)
            on0 = 1.0 if since0 < hold else 0.0
            on1 = 1.0 if since1 < hold else 0.0
            late0 = 1.0 if (since0 >= vas_after and since0 < vas_after + hold) else 0.0
            late1 = 1.0 if (since1 >= vas_after and since1 < vas_after + hold) else 0.0
            s0 = t0 and not prev0
            s1 = t1 and not prev1
            prev0 = t0
            prev1 = t1
            if by_foot:
                if s0:
                    first0 = i
                if s1:
                    first1 = i
                if first0 >= 0:
                    f = x[first0, xt0]
                    ahead0 = f - x[first0, xt0 + 1] > ahead_m
                if first1 >= 0:
                    f = x[first1, xt0 + 1]
                    ahead1 = f - x[first1, xt0] > ahead_m
            for leg in range(2):
                for j in range(nm):
                    if by_foot:
                        a = 0.0
                        for t in range(2):
                            on_t = on0 if t == 0 else on1
                            ah = ahead0 if t == 0 else ahead1
                            g0 = on_t * (0.0 if ah else 1.0)
                            g1 = on_t * (1.0 if ah else 0.0)
                            a += g0 * w_sets[0, t, leg, j]
                            a += g1 * w_sets[1, t, leg, j]
                            a += on_t * w_sets[2, t, leg, j]
                    else:
                        a = on0 * w_any[0, leg, j] + on1 * w_any[1, leg, j]
                    out[leg, j] = a + (late0 * w_vas[0, leg, j] + late1 * w_vas[1, leg, j])
            if cross:
                if s0 or s1:
                    if s0 and s1:
                        mx = max(x[i, xt0], x[i, xt0 + 1])
                    elif s0:
                        mx = x[i, xt0]
                    else:
                        mx = x[i, xt0 + 1]
                    mark[0] = mx + cross_ahead
                if t0 or t1:
                    armed[0] = True
                    armed[1] = True
                l0 = x[i, load0] > stance_load
                l1 = x[i, load0 + 1] > stance_load
                land0 = l0 and not was0
                land1 = l1 and not was1
                was0 = l0
                was1 = l1
                if land0 and armed[1]:
                    armed[1] = False
                    if x[i, xf0 + 1] < mark[0]:
                        cross_since[1] = 0
                if land1 and armed[0]:
                    armed[0] = False
                    if x[i, xf0] < mark[0]:
                        cross_since[0] = 0
                c0 = 1.0 if cross_since[0] < cross_hold else 0.0
                c1 = 1.0 if cross_since[1] < cross_hold else 0.0
                cross_since[0] += 1
                cross_since[1] += 1
                for j in range(nm):
                    out[0, j] += c0 * w_cross[j]
                    out[1, j] += c1 * w_cross[j]
            for leg in range(2):
                for j in range(nm):
                    u[i, leg * nm + j] += out[leg, j]
        scr_since[0] = since0
        scr_since[1] = since1
        touched_was[0] = prev0
        touched_was[1] = prev1
        ahead_was[0] = ahead0
        ahead_was[1] = ahead1
        if cross:
            was_on[0] = was0
            was_on[1] = was1

    @jit
    def clip_plan(u, lo, plan, first, held):
        """``u`` (n, k) clipped to lo-1 in place; when ``plan`` has rows, each is ``held``
        (the controls now) with columns ``first``… set to ``u``."""
        for i in range(u.shape[0]):
            for q in range(u.shape[1]):
                w = u[i, q]
                w = w if (w >= lo or w != w) else lo
                u[i, q] = w if (w <= 1.0 or w != w) else 1.0
        if plan.shape[0]:
            for i in range(u.shape[0]):
                for q in range(plan.shape[1]):
                    plan[i, q] = held[q]
                for q in range(u.shape[1]):
                    plan[i, first + q] = u[i, q]

    @jit
    def path_index(segs, lags, T, H):
        """Each motor path's lag modulo ``T`` and its segment's first unit."""
        lag, u0 = np.empty(len(segs), np.int64), np.empty(len(segs), np.int64)
        for k in range(len(segs)):
            lag[k] = lags[k] % T
            u0[k] = segs[k] * H
        return lag, u0

    @jit
    def batch_z(h, v, segs, js, lags, c, z):
        """``Network.forward``'s motor-neuron inputs ``z`` (T, muscles) from the
        interneurons ``h`` (T, segments·H) of periodic data: each path k's units
        ``lags[k]`` ticks later (np.roll), weighted by ``v[k]`` and summed unit by unit
        (einsum's order), added to its muscle from 0 in the paths' order, then ``c``."""
        T, H = h.shape[0], v.shape[1]
        lag, u0 = path_index(segs, lags, T, H)
        s = np.empty(len(segs))  # the tick's path sums (independent: side by side)
        for t in range(T):
            for k in range(len(segs)):
                r = t - lag[k]
                if r < 0:
                    r += T
                a = 0.0
                for q in range(H):
                    a += h[r, u0[k] + q] * v[k, q]
                s[k] = a
            for j in range(z.shape[1]):
                z[t, j] = 0.0
            for k in range(len(segs)):
                z[t, js[k]] += s[k]
            for j in range(z.shape[1]):
                z[t, j] += c[j]

    @jit
    def batch_dh(h, dz, v, segs, js, lags, dv, dpre):
        """``Network.gradient_z``'s path weights' gradient ``dv`` (paths, H; summed
        tick by tick, einsum's order) and the interneurons' input gradient ``dpre``
        (T, segments·H): each path's dz·v added ``lags[k]`` ticks earlier, from 0 in the
        paths' order, times 1 − h²."""
        T, H, W = h.shape[0], v.shape[1], h.shape[1]
        lag, u0 = path_index(segs, lags, T, H)
        dv[:] = 0.0
        for t in range(T):
            for k in range(len(segs)):
                r = t - lag[k]
                if r < 0:
                    r += T
                d = dz[t, js[k]]
                for q in range(H):
                    dv[k, q] += d * h[r, u0[k] + q]
        for r in range(T):
            for q in range(W):
                dpre[r, q] = 0.0
            for k in range(len(segs)):
                t = r + lag[k]
                if t >= T:
                    t -= T
                d = dz[t, js[k]]
                for q in range(H):
                    dpre[r, u0[k] + q] += d * v[k, q]
            for q in range(W):
                dpre[r, q] = dpre[r, q] * (1.0 - h[r, q] * h[r, q])

    @jit
    def gto_steps(b, a, z, x, y):
        """``GTOFilter.step`` over the rows of ``x`` (n, channels) into ``y``, ``z``
        carried (the same operations, tick by tick)."""
        for k in range(x.shape[0]):
            for c in range(x.shape[1]):
                xi = x[k, c]
                yi = b[0] * xi + z[0, c]
                z[0, c] = b[1] * xi - a[1] * yi + z[1, c]
                z[1, c] = b[2] * xi - a[2] * yi
                y[k, c] = yi

    @jit
    def resp_drive(first, n, w, ints, onsets, ahead, out):
        """``TouchResponse.drive`` (its sets ``w``; ``ints``: lag, hold, after,
        hold_ahead, after_ahead, span, by_foot; no recovery step) into ``out`` (n, 2,
        muscles), zeroed first; whether it adds anything (``drive`` not None)."""
        lag, span, by_foot = ints[0], ints[5], ints[6]
        n_sets = 3
        added = False
        for side in range(2):
            o = onsets[side]
            if not (o - o == 0.0) or first >= o + lag + span:
                continue
            ahead_sets = by_foot != 0 and ahead[side]
            hold = ints[3] if ahead_sets else ints[1]
            after = ints[4] if ahead_sets else ints[2]
            o0 = int(o) + lag
            any_ab = False
            for i in range(n):
                tt = first + i - o0
                if tt >= 0 and tt < hold + after:
                    any_ab = True
            if not any_ab:
                continue
            if not added:
                for i in range(n):
                    for s in range(2):
                        for q in range(out.shape[2]):
                            out[i, s, q] = 0.0
                added = True
            r0 = n_sets if ahead_sets else 0
            for i in range(n):
                tt = first + i - o0
                if tt >= 0 and tt < hold:
                    for q in range(out.shape[2]):
                        out[i, side, q] += w[r0, q]
            for i in range(n):
                tt = first + i - o0
                if tt >= hold and tt < hold + after:
                    for q in range(out.shape[2]):
                        out[i, side, q] += w[r0 + 1, q]
            for i in range(n):
                tt = first + i - o0
                if tt >= 0 and tt < hold + after:
                    for q in range(out.shape[2]):
                        out[i, 1 - side, q] += w[r0 + 2, q]
        return added

    @jit
    def resp_add(exc, ctrl, out, plan, plan_rows, act_first, held):
        """``ReflexController._add_response`` and ``update``'s plan after it: ``exc`` +=
        ``out``, ``ctrl`` its clip to 0.01-1, each plan row ``held`` with the muscles'
        columns from ``ctrl`` at ``plan_rows``."""
        nb, nm = exc.shape[0], exc.shape[2]
        for i in range(nb):
            for s in range(2):
                for q in range(nm):
                    e = exc[i, s, q] + out[i, s, q]
                    exc[i, s, q] = e
                    u = e if (e >= 0.01 or e != e) else 0.01
                    ctrl[i, s * nm + q] = u if (u <= 1.0 or u != u) else 1.0
        for i in range(plan.shape[0]):
            for q in range(plan.shape[1]):
                plan[i, q] = held[q]
            for q in range(ctrl.shape[1]):
                plan[i, act_first + q] = ctrl[plan_rows[i], q]

    @jit
    def resp_onsets(k0, n, per_step, every, touches, rows, foot_x, ints, onsets, ahead,
                    was):
        """``ReflexController._touch_onsets`` of a block's ``n`` ticks from ``k0`` (tick
        ``i`` reading row ``i // per_step`` or ``i·every``; ``foot_x``: the ankles' x
        columns)."""
        lag, span = ints[0], ints[5]
        for side in range(2):
            w = was[side]
            for i in range(n):
                now = touches[i, side] > 0.0
                o = onsets[side]
                running = (o - o == 0.0) and k0 + i < o + lag + span
                if now and not w and not running:
                    onsets[side] = k0 + i
                    r = i // per_step if per_step > 1 else i * every
                    ahead[side] = rows[r, foot_x[side]] > rows[r, foot_x[1 - side]]
                w = now
            was[side] = w

    @jit
    def net_run(phys, warn, held, sens, n_blocks, ps, n_tick, states, rows, plans,
                guard_cols, fall_h, foot_col, foot_on, on_n, ctr, a_min, bal_lag,
                resp_on, resp_w, resp_int, onsets, ahead, was, foot_x, resp_out,
                loops, meta, sensed, k_mm, l_ref, ib_force, sc, ia_exp, ib_gain, gb, ga,
                gz, loads, weight_n, contact, mean, inv_std, sig2d, gains, touches,
                touch_q, sig_buf, in_lag, in_off, sig_row, n_buf, x, h, w, b, hid2d,
                hid_buf, c_lag, hid_off, hid_row, hid, mv, t, c, bal_on, bal_buf,
                bal_par, place_buf, bal_rows, bal_sensed, bal, bal_cols, exc, ctrl,
                plan_rows, act_first, no_bal,
                per_step, every, obs_cols, n_mus3, bal_sense_cols, bal_g, touch_cols,
                place_cols, place_d, lean, alpha, no_alpha):
        """Up to ``n_blocks`` blocks of the network with the physics between them, each
        ``net_update`` (and, ``resp_on``, ``resp_drive``), then its ``ps`` steps as
        ``mujoco.rollout`` takes them (warnings cleared, ``mj_step`` until one is raised,
        the state and sensors after each step), then ``net_sense`` (and ``resp_onsets``);
        ``ctr`` (tick, block start, interneurons done) kept up to date. Stops after a
        block with a warning, a state not finite, or at any step a fall by ``fall_h`` and
        ``guard_cols`` or (``foot_col`` ≥ 0) that foot's contact, its load beyond
        ``on_n``, other than ``foot_on`` (``sim.FallGuard``); returns the blocks run."""
        for blk in range(n_blocks):
            k, first, h_first = ctr[0], ctr[1], ctr[2]
            n_r = k - first
            upto = k + a_min
            n_h = upto - h_first
            r0 = blk * ps
            plan = plans[r0:r0 + ps]
            net_update(loops, meta, n_r > 0, first, n_r, sensed, k_mm, l_ref, ib_force,
                       sc, ia_exp, ib_gain, gb, ga, gz, loads, weight_n, contact, mean,
                       inv_std, sig2d, gains, touches, touch_q, n_h, h_first, sig_buf,
                       in_lag, in_off, sig_row, n_buf, x, h, w, b, hid2d, hid_buf, k,
                       c_lag, hid_off, hid_row, hid, mv, t, c, bal_on, k - bal_lag,
                       bal_buf, bal_par, place_buf, bal_rows, bal_sensed, bal, bal_cols,
                       exc, ctrl, plan, plan_rows, act_first, held, no_bal)
            if resp_on and resp_drive(k, exc.shape[0], resp_w, resp_int, onsets, ahead,
                                      resp_out):
                resp_add(exc, ctrl, resp_out, plan, plan_rows, act_first, held)
            if n_h > 0:
                ctr[2] = upto
            ctr[1] = k
            rollout_block(phys, warn, held, sens, plan, states, rows, r0, ps)
            blk_rows = rows[r0:r0 + ps]
            net_sense(loops, meta, blk_rows, per_step, every, n_tick, obs_cols, n_mus3,
                      contact, sensed, loads, bal_sense_cols, bal_g, touch_cols, touches,
                      place_cols, place_d, place_buf, k, lean, alpha, bal_buf, no_alpha)
            if resp_on:
                resp_onsets(k, n_tick, per_step, every, touches, blk_rows, foot_x,
                            resp_int, onsets, ahead, was)
            ctr[0] = k + n_tick
            if block_ends_run(warn, states, rows, r0, ps, guard_cols, fall_h, foot_col,
                              foot_on, on_n):
                return blk + 1
        return n_blocks

    @jit
    def rollout_block(phys, warn, held, sens, plan, states, rows, r0, ps):
        """One block's ``ps`` steps as ``mujoco.rollout`` takes them: the warnings
        cleared, then each step's controls (``plan``) into ``held`` (the data's), its
        ``mj_step`` (none once a warning is raised: the state and sensors repeated), its
        full-physics state into ``states`` and sensors into ``rows`` from row ``r0``
        (``phys``: ``sim.NativePhysics.addr``)."""
        step_fn, get_fn, m, d, spec = phys[0], phys[1], phys[2], phys[3], phys[4]
        for i in range(warn.shape[0]):
            warn[i, 1] = 0
        warned = False
        for j in range(ps):
            if not warned:
                for i in range(warn.shape[0]):
                    if warn[i, 1] != 0:
                        warned = True
            if not warned:
                for q in range(held.shape[0]):
                    held[q] = plan[j, q]
                call_step(step_fn, m, d)
            call_get_state(get_fn, m, d, states[r0 + j].ctypes.data, spec)
            for q in range(sens.shape[0]):
                rows[r0 + j, q] = sens[q]

    @jit
    def block_ends_run(warn, states, rows, r0, ps, guard_cols, fall_h, foot_col, foot_on,
                       on_n):
        """Whether a native loop stops after the block at row ``r0``: a warning, a state
        not finite, or at any step a fall (``guard_cols``, ``fall_h``) or (``foot_col``
        ≥ 0) that foot's contact, its load beyond ``on_n``, other than ``foot_on``
        (``sim.FallGuard``)."""
        for i in range(warn.shape[0]):
            if warn[i, 1] != 0:
                return True
        for j in range(ps):
            for q in range(states.shape[1]):
                v = states[r0 + j, q]
                if not (v - v == 0.0):
                    return True
            row = rows[r0 + j]
            if guard_cols.shape[0] and (
                    row[guard_cols[0]] - row[guard_cols[1]] - row[guard_cols[2]] > 0.5
                    or row[guard_cols[3]] < fall_h):
                return True
            if foot_col >= 0 and ((-row[foot_col] > on_n) != foot_on):
                return True
        return False

    @jit
    def gh_run(phys, warn, held, sens, n_blocks, ps, states, rows, plans, guard_cols, fall_h,
               foot_col, foot_on, on_n, kk, size, lags, tap_cols, idx,
               loops, meta, buf, x, phi0, sign, off, low, knee_v0, has_ds, ds_load, ds_x,
               stance_load, gate0, ungated, v, stance, w_st, a, b_st, w_sw, bb, b_sw, ip, fp,
               u, scr, touch0, xt0, load0, xf0, hold, vas_after, by_foot, ahead_m, w_sets,
               w_any, w_vas, cross, cross_hold, cross_ahead, w_cross, scr_since,
               touched_was, ahead_was, armed, cross_since, was_on, mark, lo, act_first,
               gather, scale, offset, sv, place, place_cols, pa, pb, extra, lean, alpha):
        """Up to ``n_blocks`` blocks of Geyer & Herr's reflexes with the physics between
        them, as ``net_run``: each the delayed taps' indices (``DelayTaps.read_index`` at
        tick ``kk[0]``), ``gh_update``, ``rollout_block`` and ``gh_observe``; returns the
        blocks run."""
        nch = buf.shape[1]
        for blk in range(n_blocks):
            k = kk[0]
            for i in range(ps):
                for j in range(lags.shape[0]):
                    idx[i, j] = ((k + i - lags[j]) % size) * nch + tap_cols[j]
            r0 = blk * ps
            plan = plans[r0:r0 + ps]
            gh_update(loops, meta, buf, idx, x, phi0, sign, off, low, knee_v0, has_ds,
                      ds_load, ds_x, stance_load, gate0, ungated, v, stance, w_st, a, b_st,
                      w_sw, bb, b_sw, ip, fp, u, scr, touch0, xt0, load0, xf0, hold,
                      vas_after, by_foot, ahead_m, w_sets, w_any, w_vas, cross, cross_hold,
                      cross_ahead, w_cross, scr_since, touched_was, ahead_was, armed,
                      cross_since, was_on, mark, lo, plan, act_first, held)
            rollout_block(phys, warn, held, sens, plan, states, rows, r0, ps)
            gh_observe(loops, meta, rows[r0:r0 + ps], gather, scale, offset, sv, place,
                       place_cols, pa, pb, extra, lean, alpha, buf, k)
            kk[0] = k + ps
            if block_ends_run(warn, states, rows, r0, ps, guard_cols, fall_h, foot_col,
                              foot_on, on_n):
                return blk + 1
        return n_blocks

    kern = {"iir2": iir2, "balance_cols": balance_cols, "net_pre": net_pre,
            "net_push": net_push, "net_drive": net_drive, "net_out": net_out,
            "net_observe": net_observe, "bal_store": bal_store, "store_rows": store_rows,
            "place_pre": place_pre, "place_alpha": place_alpha,
            "place_drive_add": place_drive_add,
            "ring_take": ring_take, "ib_push": ib_push, "store_take": store_take,
            "bal_out": bal_out, "observe_all": observe_all, "observe_store": observe_store,
            "gh_channels": gh_channels, "gh_place_in": gh_place_in,
            "gh_features": gh_features, "gh_select": gh_select, "gh_lean": gh_lean,
            "gh_place": gh_place, "gh_touch": gh_touch, "clip_plan": clip_plan,
            "gh_sense": gh_sense, "gh_push": gh_push, "gh_laws": gh_laws,
            "loop1": loop1, "loop2": loop2, "loop_pow": loop_pow,
            "loop_atan2_cols": loop_atan2_cols, "loop_matmul": loop_matmul,
            "net_update": net_update, "net_sense": net_sense, "gh_update": gh_update,
            "gh_observe": gh_observe, "net_run": net_run, "gto_steps": gto_steps,
            "gh_run": gh_run, "batch_z": batch_z, "batch_dh": batch_dh}
    kern["loops"] = numpy_loops(kern)  # None: NumPy's loops not found as expected
    return kern


_KERNELS: dict | bool | None = False  # False: not looked for yet


def kernels() -> dict | None:
    """The compiled kernels by name, or None where the NumPy code runs (looked up once)."""
    global _KERNELS
    if _KERNELS is False:
        _KERNELS = _load()
    return _KERNELS


def use_numpy(flag: bool = True) -> None:
    """Force the NumPy code (True) or look for the kernels again (False); for tests."""
    global _KERNELS
    _KERNELS = None if flag else False


__all__ = ["ENV", "LOOPS", "kernels", "numpy_loops", "use_numpy"]
