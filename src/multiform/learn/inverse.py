"""The auxiliary inverse model (the paper's Fig. 4): how to actuate the joints for a desired
end-effector maneuver, learned from the robot's *own* motion data, never from the mentor's.

The maneuver the mentor teaches is an end-effector command (for the arm: a velocity along the swing
axis). A fixed servo turns it into a desired task acceleration ``a`` (linear and angular, 6-D) from
the robot's own sensors; the learned part maps the joint state, the state of the load the hand
carries ``p`` (for the arm: the pendulum's angle and rate, from its hinge encoder) and ``a`` to joint
torques,

    τ = f(q, q̇, p, a),   f = a linear map on basis features + a GP on its residual,

i.e. inverse dynamics in task space with the payload (mass matrix, Jacobian, gravity, Coriolis, the
pendulum's reaction — none of it given). The load matters: a swinging 0.1 kg pendulum pulls on the
flange enough that an arm which ignores it pumps the pendulum wrongly and the learned swing-up
fails (0/12 trials, against 12/12 with the load modelled). The linear part carries the bulk and keeps
extrapolation sane; its basis is physical: ``q, q̇, a`` and the load's features (for a pendulum
gravity, centripetal and θ̈-coupling terms in ``θ, ω`` and the pivot's acceleration); the GP (:class:`~.gp.GPLaw`) picks up the curvature.

Servos are registered by name (:data:`~.servos.SERVOS`, filled by the package of the robot that has
the servo, e.g. :mod:`multiform.envs`) with the load features they need, so a saved model names its
servo and loading it can never run code from the file.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator

from ..errors import InvalidInput
from ..io import load_npz, save_npz
from .compiled import gp_mean_one
from .gp import GPLaw
from .servos import SERVOS, Servo, known_servos, register_servo, servo_factory  # noqa: F401  (the registry)

KIND = "inverse_model"
VERSION = 2                     # 2: the residual GP's metadata nested under "gp"


class InverseDynamicsModel(BaseEstimator):
    """Learned ``(q, q̇, load, a) → τ``; :meth:`torques` is the executor's inverse-model interface.

    :meth:`fit` takes observation rows (the robot's sensors), the achieved task accelerations and the
    torques that produced them. After fitting: ``coef_`` (linear part, on standardised features),
    ``gp_`` (residual GP), ``f_mean_``/``f_scale_``, ``n_train_``.
    """

    def __init__(self, servo: str = "arm_pendulum", n_joints: int = 6, ridge: float = 1e-6,
                 n_inducing: int = 300, n_hyper: int = 800, random_state: int = 0):
        self.servo = servo
        self.n_joints = n_joints
        self.ridge = ridge
        self.n_inducing = n_inducing
        self.n_hyper = n_hyper
        self.random_state = random_state

    def _servo(self) -> Servo:
        factory = servo_factory(self.servo)
        if factory is None:
            raise ValueError(f"unknown servo {self.servo!r} (known: {', '.join(known_servos())})")
        return factory()

    def _joint_index(self, sv: Servo) -> list[int]:
        names = list(sv.observation_names)
        n = self.n_joints
        return [names.index(f"q{i + 1}") for i in range(n)] + [names.index(f"qd{i + 1}") for i in range(n)]

    def _inputs(self, O: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """GP inputs ``[q, q̇, load, a]`` and linear features ``[q, q̇, a, basis]`` of observation rows."""
        sv = self._servo()
        qi = self._joint_index(sv)
        Oc, Ac = O.T, A.T
        load = np.stack(np.broadcast_arrays(*sv.load(np, Oc, Ac)), axis=1)
        basis = np.stack(np.broadcast_arrays(*sv.basis(np, Oc, Ac)), axis=1)
        return np.c_[O[:, qi], load, A], np.c_[O[:, qi], A, basis]

    def fit(self, O: np.ndarray, A: np.ndarray, tau: np.ndarray) -> InverseDynamicsModel:
        """``O`` observation rows, ``A`` achieved task accelerations (m, 6), ``tau`` torques (m, n)."""
        O, A, tau = (np.asarray(v, dtype=np.float64) for v in (O, A, tau))
        n = self.n_joints
        if A.shape != (len(O), 6) or tau.shape != (len(O), n):
            raise ValueError(f"expected A (m, 6) and tau (m, {n}) for {len(O)} rows; got {A.shape}, {tau.shape}")
        if not (np.all(np.isfinite(O)) and np.all(np.isfinite(A)) and np.all(np.isfinite(tau))):
            raise ValueError("non-finite training data")
        G, F = self._inputs(O, A)
        self.f_mean_ = F.mean(0)
        self.f_scale_ = np.where(F.std(0) > 1e-9, F.std(0), 1.0)
        Fs = np.c_[(F - self.f_mean_) / self.f_scale_, np.ones(len(F))]
        self.coef_ = np.linalg.solve(Fs.T @ Fs + self.ridge * len(Fs) * np.eye(Fs.shape[1]), Fs.T @ tau)
        resid = tau - Fs @ self.coef_
        self.gp_ = GPLaw(n_hyper=self.n_hyper, n_restarts=0, sparse_threshold=1000, n_inducing=self.n_inducing,
                         random_state=self.random_state).fit(G, resid)
        self.n_train_ = len(O)
        self._prepare()
        return self

    def _prepare(self) -> None:
        self._sv = sv = self._servo()
        probe = sv.features(np.zeros(len(sv.observation_names)), (0.0,))
        d_gp, d_lin = self.gp_.n_features_in_, self.coef_.shape[0] - 1
        if probe.shape != (d_gp + d_lin,):
            raise ValueError(f"servo {self.servo!r} gives {probe.shape[0]} features, the model reads "
                             f"{d_gp} + {d_lin} ({self.n_joints} joints)")
        # The linear part folded into one affine map of the raw features: τ_lin = F·W + b,
        # evaluated with the residual GP's mean in one compiled call.
        self._W = self.coef_[:-1] / self.f_scale_[:, None]
        self._b = self.coef_[-1] - self.f_mean_ @ self._W
        self._plan, self._with_x = self.gp_.affine_plan(self._W, self._b)
        self._n_gp = d_gp

    def predict(self, O: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Torques for observation rows ``O`` and task accelerations ``A``."""
        G, F = self._inputs(np.atleast_2d(O), np.atleast_2d(A))
        return F @ self._W + self._b + self.gp_.predict(G)

    def torques(self, obs: np.ndarray, command: Sequence[float]) -> np.ndarray:
        """The executor's interface: the servo's desired task acceleration, then the learned map.

        Two compiled calls per state: the servo's features (:class:`Servo`), then the residual GP
        and the linear part (one precomputed affine map) together."""
        both = self._sv.features(obs, tuple(command))
        n = self._n_gp
        return gp_mean_one(both[:n], both if self._with_x else both[n:], *self._plan)

    def summary(self) -> dict[str, Any]:
        s = self.gp_.summary()
        return {"servo": self.servo, "n_train": int(self.n_train_), "residual_gp": s["mode"], "n_inducing": s["n_inducing"]}

    # -- persistence ---------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        """The linear part and the residual GP's arrays (under ``gp/``) in one ``.npz`` (no pickle)."""
        gp_arrays, gp_meta = self.gp_.to_arrays()
        arrays = {"coef": self.coef_, "f_mean": self.f_mean_, "f_scale": self.f_scale_,
                  **{f"gp/{k}": v for k, v in gp_arrays.items()}}
        meta = {"servo": self.servo, "n_joints": self.n_joints, "ridge": self.ridge, "n_inducing": self.n_inducing,
                "n_hyper": self.n_hyper, "random_state": self.random_state, "n_train": int(self.n_train_),
                "gp": gp_meta}
        save_npz(path, arrays, meta, KIND, VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike) -> InverseDynamicsModel:
        arrays, meta = load_npz(path, KIND, VERSION)
        f = str(path)
        factory = servo_factory(meta.get("servo"))
        if factory is None:
            raise InvalidInput(f"unknown servo {meta.get('servo')!r} (known: {', '.join(known_servos())})", file=f,
                               element="servo")
        n = int(meta.get("n_joints", 0))
        sv = factory()
        probe = [0.0] * len(sv.observation_names)
        d = 2 * n + 6 + len(sv.basis(math, probe, [0.0] * 6))
        d_gp = 2 * n + 6 + len(sv.load(math, probe, [0.0] * 6))
        for key, shape in (("coef", (d + 1, n)), ("f_mean", (d,)), ("f_scale", (d,))):
            if key not in arrays or arrays[key].shape != shape:
                got = arrays[key].shape if key in arrays else "missing"
                raise InvalidInput(f"array {key!r} is {got}, expected {shape}", file=f, element=key)
        m = cls(servo=meta["servo"], n_joints=n, ridge=float(meta["ridge"]), n_inducing=int(meta["n_inducing"]),
                n_hyper=int(meta["n_hyper"]), random_state=int(meta["random_state"]))
        m.coef_, m.f_mean_, m.f_scale_ = arrays["coef"], arrays["f_mean"], arrays["f_scale"]
        if not isinstance(meta.get("gp"), dict):
            raise InvalidInput("metadata of the residual GP is missing", file=f, element="gp")
        gp_arrays = {k[3:]: v for k, v in arrays.items() if k.startswith("gp/")}
        m.gp_ = GPLaw.from_arrays(gp_arrays, meta["gp"], f, prefix="gp/")
        if m.gp_.n_features_in_ != d_gp:
            raise InvalidInput(f"the residual GP reads {m.gp_.n_features_in_} inputs, expected {d_gp}", file=f,
                               element="gp")
        m.n_train_ = int(meta.get("n_train", 0))
        try:
            m._prepare()
        except ValueError as exc:
            raise InvalidInput(str(exc), file=f, element="n_joints") from None
        return m
