"""The storage layout of the hidden units and the wake-sleep loops that use it (private).

Hidden units are stored minor-axis-fastest along the grid's shorter side: for the paper's 16 x 48
grid, column-major (storage index = column * 16 + row). A square envelope window of half-width h
then covers one contiguous run of storage rows (6 * 16 + 7 = 103 for h = 3) in which the units
outside the window carry envelope weight exactly 0. Every per-step operation is then a BLAS call or
an elementwise ufunc on contiguous same-shape blocks, the cheapest kinds of numpy call; the
zero-weight units in a run are left unchanged exactly (added 0, scaled by 1, rectified at 0 or
above).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where each grid unit is stored and the truncated envelope around each unit.

    Attributes:
      storage_of_grid: (n_hidden,) storage index of each grid unit (grid order is row-major).
      grid_of_storage: (n_hidden,) grid index of each storage row.
      starts, stops: (n_hidden,) for each unit in storage order, the contiguous storage run
        [start, stop) that holds its envelope window.
      envelopes: for each unit in storage order, the envelope on its run, shape (stop - start,),
        float64, exactly 0 outside the square window.
      minor: the number of storage rows per major line (16 for the paper's grid).
      boxes: for each unit in storage order, its window as (major0, major1, minor0, minor1):
        storage rows major * minor + m for major0 <= major < major1, minor0 <= m < minor1.
    """

    storage_of_grid: np.ndarray
    grid_of_storage: np.ndarray
    starts: np.ndarray
    stops: np.ndarray
    envelopes: tuple
    minor: int
    boxes: tuple

    @classmethod
    def build(cls, hidden_shape, sigma: float, cutoff: float) -> Layout:
        """Returns the layout of a ``hidden_shape`` grid with envelope ``sigma`` (grid units)
        truncated at half-width ``ceil(cutoff * sigma)``."""
        rows, cols = (int(v) for v in hidden_shape)
        half = int(np.ceil(cutoff * sigma))
        grid_r, grid_c = np.divmod(np.arange(rows * cols), cols)
        transposed = rows <= cols  # the shorter side varies fastest in storage
        if transposed:
            storage_of_grid = grid_c * rows + grid_r
            minor = rows
        else:
            storage_of_grid = grid_r * cols + grid_c
            minor = cols
        grid_of_storage = np.argsort(storage_of_grid)
        starts = np.empty(rows * cols, dtype=np.int64)
        stops = np.empty(rows * cols, dtype=np.int64)
        envelopes, boxes = [], []
        for i, k in enumerate(grid_of_storage):
            r, c = int(grid_r[k]), int(grid_c[k])
            r0, r1 = max(r - half, 0), min(r + half + 1, rows)
            c0, c1 = max(c - half, 0), min(c + half + 1, cols)
            if transposed:
                (major0, major1), (minor0, minor1) = (c0, c1), (r0, r1)
            else:
                (major0, major1), (minor0, minor1) = (r0, r1), (c0, c1)
            start, stop = major0 * minor + minor0, (major1 - 1) * minor + minor1
            run = grid_of_storage[start:stop]
            dr, dc = grid_r[run] - r, grid_c[run] - c
            inside = (np.abs(dr) <= half) & (np.abs(dc) <= half)
            envelope = np.where(inside, np.exp(-0.5 * (dr**2 + dc**2) / sigma**2), 0.0)
            starts[i], stops[i] = start, stop
            envelopes.append(envelope)
            boxes.append((major0, major1, minor0, minor1))
        return cls(
            storage_of_grid, grid_of_storage, starts, stops, tuple(envelopes), minor, tuple(boxes)
        )


def schedule(model, n: int) -> np.ndarray:
    """Returns the rate factors of the next ``n`` steps, shape (n,), float64, equal to
    ``model.learning_rate_factor`` step by step (same IEEE operations, vectorised)."""
    total = float(model.n_steps_total)
    remaining = total - (model.n_steps_ + np.arange(n, dtype=np.float64))
    decay = model.decay_fraction * total
    factor = np.ones(n)
    if decay > 0:
        ramp = remaining < decay
        factor[ramp] = remaining[ramp] / decay
    factor[remaining <= 0] = 0.0
    return factor


RENORMALISE_EVERY = 128


def renormalise(w_bu: np.ndarray) -> None:
    """Scales every row of ``w_bu`` to unit length, in place.

    The fast loop scales each changed row by a factor computed from the row's norm before the
    update taken as 1; in float32 that factor, close to 1, is rounded to 6e-8, which for rows far
    out in the envelope is larger than the change it corrects. Rescaling all rows every
    ``RENORMALISE_EVERY`` global steps (a fixed step count, so chunked training is unchanged)
    keeps the norms within a few 1e-6 of 1 (a row near a frequent winner is scaled at
    most 128 times between rescalings, each scale factor rounded by at most 3e-8).
    """
    norms = np.sqrt(np.einsum("ij,ij->i", w_bu, w_bu))
    w_bu /= norms[:, None]


class FastLoop:
    """Views and buffers for the default training loop, built once per weight arrays.

    Not part of the learned state: it is rebuilt after loading, copying or unpickling.
    """

    def __init__(self, w_bu: np.ndarray, w_td_t: np.ndarray, layout: Layout, params: dict):
        dtype = w_bu.dtype
        n_hidden, n_input = w_bu.shape
        minor = layout.minor
        self.w_bu, self.w_td_t = w_bu, w_td_t
        self.params = dict(params)
        self.eta = float(params["eta"])
        self.epsilon = float(params["epsilon"])
        self.boost = float(params["motor_change_boost"])
        self.dtype = dtype
        width = int((layout.stops - layout.starts).max())
        box = max((m1 - m0) * (n1 - n0) for m0, m1, n0, n1 in layout.boxes)
        self.pair = np.zeros((n_input, 2), dtype)  # columns: z^s of this step, z of the next
        self.products = np.zeros((n_hidden, 2), dtype)
        self.z_sleep = np.zeros(n_input, dtype)
        self.recon = np.zeros(n_input, dtype)
        self.err = np.zeros((1, n_input), dtype)
        # Reads (BLAS products) use a unit's contiguous run of storage rows; writes use the
        # window's rows only, a (majors, minors, 180) strided view of the same storage.
        w_bu3 = w_bu.reshape(n_hidden // minor, minor, n_input)
        w_td3 = w_td_t.reshape(n_hidden // minor, minor, n_input)
        tmp = np.zeros((box, n_input), dtype)
        zeros = np.zeros((box, n_input), dtype)
        ones = np.ones(width, dtype)
        x, y = np.zeros(width, dtype), np.zeros(width, dtype)
        c1 = np.zeros(width + minor, dtype)
        self.wake, self.sleep, self.window_positions = [], [], []
        for i in range(n_hidden):
            start, stop = int(layout.starts[i]), int(layout.stops[i])
            major0, major1, minor0, minor1 = layout.boxes[i]
            shape = (major1 - major0, minor1 - minor0)
            k = shape[0] * shape[1]
            m = stop - start
            positions = (np.arange(shape[0])[:, None] * minor + np.arange(shape[1])).ravel()
            self.window_positions.append(positions)
            g = layout.envelopes[i]
            g_box = g[positions]
            a = self.epsilon * g
            d = a / (1.0 - a)  # (1 - a) w + a z^s = (1 - a) (w + d z^s)
            self.wake.append(
                (
                    w_td_t[start:stop],
                    g.astype(dtype),
                    (self.eta * g_box)[:, None].astype(dtype),
                    (self.eta * self.boost * g_box)[:, None].astype(dtype),
                    tmp[:k],
                    tmp[:k].reshape(shape + (n_input,)),
                    w_td3[major0:major1, minor0:minor1],
                    zeros[:k].reshape(shape + (n_input,)),
                )
            )
            self.sleep.append(
                (
                    w_bu3[major0:major1, minor0:minor1],
                    self.products[start:stop, 0],
                    self.products[start:stop, 1],
                    (2.0 * d).astype(dtype),
                    (d * d).astype(dtype),
                    d.astype(dtype),
                    d[positions][:, None].astype(dtype),
                    tmp[:k],
                    tmp[:k].reshape(shape + (n_input,)),
                    ones[:m],
                    x[:m],
                    y[:m],
                    c1[:m],
                    c1[: shape[0] * minor].reshape(shape[0], minor)[:, : shape[1], None],
                )
            )
        self.envelopes = layout.envelopes

    def bound_to(self, w_bu: np.ndarray, w_td_t: np.ndarray, params: dict) -> bool:
        """Returns whether these views and tables belong to these weights and hyper-parameters."""
        return self.w_bu is w_bu and self.w_td_t is w_td_t and self.params == params

    def run(
        self,
        z: np.ndarray,
        changed: np.ndarray,
        dreams: np.ndarray,
        factors: np.ndarray,
        first_step: int,
        winners: list | None = None,
    ) -> None:
        """Trains on ``z`` (n, 180) in the weights' dtype, from global step ``first_step``; see
        ``Associator._train_fast``. ``dreams`` are storage indices, ``factors`` the schedule;
        ``winners``, if given, a list that receives each wake's winner (storage index)."""
        n = z.shape[0]
        if n == 0:
            return
        w_bu = self.w_bu
        pair, products = self.pair, self.products
        z_sleep, recon, err = self.z_sleep, self.recon, self.err
        err1 = err[0]
        z_row = z_sleep[None]
        next_z, sleep_z = pair[:, 1], pair[:, 0]
        r, r_sleep = products[:, 1], products[:, 0]
        wake, sleep = self.wake, self.sleep
        dot, add, multiply, subtract, maximum, sqrt, reciprocal = (
            np.dot,
            np.add,
            np.multiply,
            np.subtract,
            np.maximum,
            np.sqrt,
            np.reciprocal,
        )
        dtype = self.dtype
        factor_list = factors.tolist()
        changed_list = changed.tolist()
        dream_list = dreams.tolist()
        # r = W_bu z_0; afterwards each step's dense product brings the next wake's r along.
        next_z[:] = z[0]
        dot(w_bu, pair, out=products)
        for t in range(n):
            factor = factor_list[t]
            last = t + 1 == n
            if factor == 0.0:  # after n_steps_total nothing is learned
                if winners is not None:
                    winners.append(int(r.argmax()))
                if not last:
                    next_z[:] = z[t + 1]
                    dot(w_bu, pair, out=products)
                continue
            # Wake: winner of r = W_bu z, r^c its envelope, z~ = W_td r^c,
            # dW_td = eta' r^c (z - z~), rectified.
            winner = r.argmax()
            if winners is not None:
                winners.append(winner)
            run, g, g_eta, g_boost, tmp, tmp3, window, zeros = wake[winner]
            dot(g, run, out=recon)
            subtract(z[t], recon, out=err1)
            if factor == 1.0:
                g_rate = g_boost if changed_list[t] else g_eta
            else:
                rate = self.eta * factor * (self.boost if changed_list[t] else 1.0)
                g_rate = (rate * g[self.window_positions[winner]])[:, None].astype(dtype)
            dot(g_rate, err, out=tmp)
            add(window, tmp3, out=window)
            maximum(window, zeros, out=window)
            # Sleep: z^s = W_td r^s; one dense pass gives r~ = W_bu z^s and the next wake's W_bu z.
            run, g = wake[dream_list[t]][:2]
            dot(g, run, out=z_sleep)
            sleep_z[:] = z_sleep
            if not last:
                next_z[:] = z[t + 1]
            dot(w_bu, pair, out=products)
            winner = r_sleep.argmax()
            window, p_sleep, p_next, d2, dd, d, d_col, tmp, tmp3, ones, x, y, c1, c1_box = sleep[
                winner
            ]
            if factor != 1.0:
                a = self.epsilon * factor * self.envelopes[winner]
                d64 = a / (1.0 - a)
                d2, dd = (2.0 * d64).astype(dtype), (d64 * d64).astype(dtype)
                d = d64.astype(dtype)
                d_col = d64[self.window_positions[winner]][:, None].astype(dtype)
            zz, zz_next = dot(z_sleep, pair).tolist()
            # w' = (w + d z^s) / |w + d z^s|, |w + d z^s|^2 = 1 + 2 d (w . z^s) + d^2 |z^s|^2
            multiply(d2, p_sleep, out=x)
            multiply(dd, zz, out=y)
            add(x, y, out=x)
            add(x, ones, out=x)
            sqrt(x, out=x)
            reciprocal(x, out=c1)
            dot(d_col, z_row, out=tmp)
            add(window, tmp3, out=window)
            multiply(window, c1_box, out=window)
            # The next wake's r on the changed rows: w' . z = c1 (w . z + d z^s . z).
            multiply(d, zz_next, out=y)
            add(p_next, y, out=p_next)
            multiply(p_next, c1, out=p_next)
            if (first_step + t + 1) % RENORMALISE_EVERY == 0:
                renormalise(w_bu)
