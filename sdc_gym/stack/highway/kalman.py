"""filterpy's Kalman filter with its matrix products in one fixed order.

:class:`filterpy.kalman.KalmanFilter` multiplies with ``np.dot`` and inverts with
``np.linalg.inv``, both handed to OpenBLAS, whose kernels (chosen per processor) round
differently: tracked cars' states would then differ in the last bit between machines, and
over an episode that can change a decision. :class:`FixedOrderKalmanFilter` is filterpy's
filter (its state, attributes and every other method) with :meth:`predict` and
:meth:`update` computing filterpy's very equations through
:mod:`sdc_gym.geometry.fixed_order`.
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any

import numpy as np
from filterpy.common import reshape_z
from filterpy.kalman import KalmanFilter

from sdc_gym.geometry.fixed_order import inverse, matmul


class FixedOrderKalmanFilter(KalmanFilter):
    """A linear Kalman filter (filterpy's) whose results do not depend on the processor.

    Control inputs (``B``, ``u``) are not supported: the tracker has none.
    """

    def __init__(self, dim_x: int, dim_z: int) -> None:
        super().__init__(dim_x=dim_x, dim_z=dim_z)
        self.inv = inverse

    def predict(self, u: Any = None, B: Any = None, F: Any = None, Q: Any = None) -> None:
        """filterpy's predict step: ``x = F x``, ``P = alpha^2 F P F^T + Q``."""
        if u is not None or B is not None:
            raise ValueError("FixedOrderKalmanFilter.predict: control inputs are not supported")
        F = self.F if F is None else F
        Q = self.Q if Q is None else (np.eye(self.dim_x) * Q if np.isscalar(Q) else Q)
        self.x = matmul(F, self.x)
        self.P = self._alpha_sq * matmul(matmul(F, self.P), F.T) + Q
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()

    def update(self, z: Any, R: Any = None, H: Any = None) -> None:
        """filterpy's update step (Joseph form of the covariance update)."""
        self._log_likelihood = None
        self._likelihood = None
        self._mahalanobis = None
        if z is None:
            super().update(None)
            return
        R = self.R if R is None else (np.eye(self.dim_z) * R if np.isscalar(R) else R)
        if H is None:
            z = reshape_z(z, self.dim_z, self.x.ndim)
            H = self.H
        self.y = z - matmul(H, self.x)
        PHT = matmul(self.P, H.T)
        self.S = matmul(H, PHT) + R
        self.SI = self.inv(self.S)
        self.K = matmul(PHT, self.SI)
        self.x = self.x + matmul(self.K, self.y)
        I_KH = self._I - matmul(self.K, H)
        self.P = matmul(matmul(I_KH, self.P), I_KH.T) + matmul(matmul(self.K, R), self.K.T)
        self.z = deepcopy(z)
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
