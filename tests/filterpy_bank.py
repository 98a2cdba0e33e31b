"""FilterPy's Kalman filters, one per IMM mode, as the reference the IMM tests compare to.

Shared by ``test_imm_filter`` (CV / coordinated turn / CA modes) and
``test_imm_stationary`` (CV + stationary).
"""

import numpy as np


def filterpy_bank(modes, dt, H, R, x0, P0):
    """One FilterPy ``KalmanFilter`` per mode of ``modes`` over ``dt``, each in the full
    state (its mode's rows and columns of ``x0``/``P0``), and the stacked mode states."""
    from filterpy.kalman import KalmanFilter

    n = modes.state_dim
    bank, xs, Ps = [], np.zeros((1, modes.n_modes, n)), np.zeros((1, modes.n_modes, n, n))
    for j, m in enumerate(modes.models):
        idx = modes.mode_indices[j]
        F = np.zeros((n, n))
        F[np.ix_(idx, idx)] = m.transition(dt)
        Q = np.zeros((n, n))
        Q[np.ix_(idx, idx)] = m.noise(dt)
        kf = KalmanFilter(n, H.shape[0])
        kf.F, kf.Q, kf.H, kf.R = F, Q, H, R
        xi = np.zeros(n)
        xi[idx] = x0[idx]
        Pi = np.zeros((n, n))
        Pi[np.ix_(idx, idx)] = P0[np.ix_(idx, idx)]
        kf.x, kf.P = xi.copy(), Pi.copy()
        bank.append(kf)
        xs[0, j], Ps[0, j] = xi, Pi
    return bank, xs, Ps
