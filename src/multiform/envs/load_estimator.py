"""Estimate the free part of a nunchaku from the load it puts on the wrist.

The robot cannot see the rods. While the hand holds one rod, everything that hangs from that rod's
chain end (the chain and the free rod) pulls on the held rod at one point, the *pivot*; the held rod
and the hand pass that pull to the wrist force/torque sensor. With the hand's own motion known from
its joints (proprioception), Newton's law on the hand and the held rod recovers the pull:

    F_pull = m_hand (a_hand - g) + m_held (a_held - g) - F_wrist          (world frame, flip plane)

The free part is modelled as a planar double pendulum hanging from the accelerating pivot: the chain
as a massless link of length ``l_chain`` with half the chain's mass at each end, the free rod as a
uniform compound pendulum hinged at the chain's end. Its equations of motion, driven by the pivot's
acceleration (effective gravity G = g - a_pivot), predict the state; the pull it exerts on the pivot
is the measurement. An extended Kalman filter on (chain angle, rod angle, their rates) fuses the two;
its Jacobians are taken by finite differences of the model. A chain cannot push: where the model's
chain tension goes negative the chain is slack, the free part falls freely and pulls nothing.
Innovation gating drops samples that no state explains (contacts putting loads on the hand that the
model does not have: the free rod slapping the hand or hitting the held rod).

Angles are in the flip plane: 0 points straight down (world frame) or along the palm normal (hand
frame), positive towards world +x / hand +x. The filter runs in the world frame;
:meth:`LoadEstimator.update` returns the free rod's angle and rate relative to the hand. Plain
floats and unrolled 4x4 algebra: one update costs a few tens of microseconds, so it runs in every
1 kHz control step.
"""

from __future__ import annotations

import math

GRAVITY = 9.81
TWO_PI = 2.0 * math.pi


def _wrap(a: float) -> float:
    a = math.fmod(a + math.pi, TWO_PI)
    if a <= 0.0:
        a += TWO_PI
    return a - math.pi


class LoadEstimator:
    """Extended Kalman filter for the chain and free rod of a nunchaku held by its other rod.

    Parameters are the nominal model (kg, m) and the filter's noise levels: ``accel_noise`` is the
    standard deviation of unmodelled angular acceleration (chain bending, friction) in rad/s^2,
    ``force_noise`` + ``force_rel`` * |pull| that of the pull measurement per axis in N, ``gate``
    the largest normalised innovation squared that is accepted.
    """

    def __init__(self, m_hand: float = 0.35, m_held: float = 0.2, m_chain: float = 0.06, l_chain: float = 0.12,
                 m_rod: float = 0.2, l_rod: float = 0.30, damping: float = 0.0005, accel_noise: float = 80.0,
                 force_noise: float = 0.3, force_rel: float = 0.08, gate: float = 50.0):
        self.m_hand = m_hand
        self.m_held = m_held
        self.m_chain = m_chain
        self.l_chain = l_chain
        self.m_rod = m_rod
        self.l_rod = l_rod
        self.damping = damping
        self.accel_noise = accel_noise
        self.force_noise = force_noise
        self.force_rel = force_rel
        self.gate = gate
        self.reset()

    def reset(self, pivot: tuple[float, float] = (0.065, -0.0275), held_com: tuple[float, float] = (-0.085, -0.0275),
              angle: float | None = 0.0, rate: float = 0.0, angle_std: float = 0.25) -> None:
        """Start tracking; ``pivot`` and ``held_com`` are in the hand frame (x, z) [m].

        ``angle`` is the prior of the free part's world angle (a nunchaku picked up hangs: 0) with
        standard deviation ``angle_std``; ``None`` takes it from the direction of the first pull.
        """
        self.pivot = (float(pivot[0]), float(pivot[1]))
        self.held_com = (float(held_com[0]), float(held_com[1]))
        a = 0.0 if angle is None else float(angle)
        self._init = angle is not None
        self.x = [a, a, float(rate), float(rate)]
        v = angle_std * angle_std
        self.P = [[v, 0.9 * v, 0.0, 0.0], [0.9 * v, v, 0.0, 0.0], [0.0, 0.0, 4.0, 0.0], [0.0, 0.0, 0.0, 4.0]]
        self.pull = (0.0, 0.0)
        self.rejected = 0

    @property
    def chain_angle(self) -> float:
        """Estimated world angle of the chain [rad]."""
        return self.x[0]

    def _dyn(self, t1: float, t2: float, w1: float, w2: float, gx: float, gz: float, wh: float):
        """Angular accelerations of chain and rod, and their pull on the pivot."""
        l1 = self.l_chain
        mc = 0.5 * self.m_chain
        m2 = self.m_rod
        d = 0.5 * self.l_rod
        s1, c1 = math.sin(t1), math.cos(t1)
        s2, c2 = math.sin(t2), math.cos(t2)
        sd, cd = math.sin(t1 - t2), math.cos(t1 - t2)
        m11 = (mc + m2) * l1 * l1
        m12 = m2 * l1 * d * cd
        m22 = m2 * d * d + m2 * self.l_rod * self.l_rod / 12.0
        b = self.damping
        r1 = (mc + m2) * l1 * (gx * c1 + gz * s1) - m2 * l1 * d * sd * w2 * w2 - b * (2.0 * w1 - wh - w2)
        r2 = m2 * d * (gx * c2 + gz * s2) + m2 * l1 * d * sd * w1 * w1 - b * (w2 - w1)
        det = m11 * m22 - m12 * m12
        a1 = (m22 * r1 - m12 * r2) / det
        a2 = (m11 * r2 - m12 * r1) / det
        w1s, w2s = w1 * w1, w2 * w2
        apx = l1 * (a1 * c1 - w1s * s1)
        apz = l1 * (a1 * s1 + w1s * c1)
        acx = apx + d * (a2 * c2 - w2s * s2)
        acz = apz + d * (a2 * s2 + w2s * c2)
        fx = mc * (gx - apx) + m2 * (gx - acx)
        fz = mc * (gz - apz) + m2 * (gz - acz)
        if fx * s1 - fz * c1 < 0.0:
            return (gx * c1 + gz * s1) / l1, 0.0, mc * gx, mc * gz
        return a1, a2, fx + mc * gx, fz + mc * gz

    def update(self, f_hand: tuple[float, float], q: float, w: float, alpha: float,
               ax: float, az: float, dt: float) -> tuple[float, float]:
        """One filter step; returns (angle, rate) of the free rod relative to the hand.

        ``f_hand`` is the wrist force in the hand frame (x, z) [N]; ``q``, ``w``, ``alpha`` the hand's
        angle, angular velocity and acceleration in the flip plane; ``ax``, ``az`` the acceleration of
        the hand's origin (the wrist) in the world [m/s^2].
        """
        cq, sq = math.cos(q), math.sin(q)
        fwx = f_hand[0] * cq - f_hand[1] * sq
        fwz = f_hand[0] * sq + f_hand[1] * cq
        hx, hz = self.held_com
        cx, cz = hx * cq - hz * sq, hx * sq + hz * cq
        px, pz = self.pivot
        rx, rz = px * cq - pz * sq, px * sq + pz * cq
        wh2 = w * w
        yx = self.m_hand * ax + self.m_held * (ax - alpha * cz - wh2 * cx) - fwx
        yz = self.m_hand * (az + GRAVITY) + self.m_held * (az + alpha * cx - wh2 * cz + GRAVITY) - fwz
        self.pull = (yx, yz)
        gx = -(ax - alpha * rz - wh2 * rx)
        gz = -GRAVITY - (az + alpha * rx - wh2 * rz)
        x0, x1, x2, x3 = self.x
        if not self._init:
            x0 = x1 = math.atan2(yx, -yz)
            self._init = True
        dyn = self._dyn
        a1, a2, _, _ = dyn(x0, x1, x2, x3, gx, gz, w)
        x0, x1, x2, x3 = x0 + x2 * dt, x1 + x3 * dt, x2 + a1 * dt, x3 + a2 * dt
        base = dyn(x0, x1, x2, x3, gx, gz, w)
        # Jacobian columns of (a1, a2, hx, hz) w.r.t. the state, by forward differences
        jac = []
        for k, eps in ((0, 1e-4), (1, 1e-4), (2, 1e-3), (3, 1e-3)):
            xs = [x0, x1, x2, x3]
            xs[k] += eps
            r = dyn(xs[0], xs[1], xs[2], xs[3], gx, gz, w)
            jac.append(((r[0] - base[0]) / eps, (r[1] - base[1]) / eps, (r[2] - base[2]) / eps,
                        (r[3] - base[3]) / eps))
        ja1 = [jac[k][0] for k in range(4)]
        ja2 = [jac[k][1] for k in range(4)]
        hxr = [jac[k][2] for k in range(4)]
        hzr = [jac[k][3] for k in range(4)]
        P = self.P
        # F = I + dt * [[0 0 1 0], [0 0 0 1], ja1, ja2];  A = F P
        A0 = [P[0][j] + dt * P[2][j] for j in range(4)]
        A1 = [P[1][j] + dt * P[3][j] for j in range(4)]
        A2 = [P[2][j] + dt * (ja1[0] * P[0][j] + ja1[1] * P[1][j] + ja1[2] * P[2][j] + ja1[3] * P[3][j])
              for j in range(4)]
        A3 = [P[3][j] + dt * (ja2[0] * P[0][j] + ja2[1] * P[1][j] + ja2[2] * P[2][j] + ja2[3] * P[3][j])
              for j in range(4)]
        A = (A0, A1, A2, A3)
        # P' = A F^T + Q
        qn = (self.accel_noise * dt) ** 2
        Pn = [[0.0] * 4 for _ in range(4)]
        for i in range(4):
            Ai = A[i]
            Pn[i][0] = Ai[0] + dt * Ai[2]
            Pn[i][1] = Ai[1] + dt * Ai[3]
            Pn[i][2] = Ai[2] + dt * (ja1[0] * Ai[0] + ja1[1] * Ai[1] + ja1[2] * Ai[2] + ja1[3] * Ai[3])
            Pn[i][3] = Ai[3] + dt * (ja2[0] * Ai[0] + ja2[1] * Ai[1] + ja2[2] * Ai[2] + ja2[3] * Ai[3])
        Pn[2][2] += qn
        Pn[3][3] += qn
        # measurement: S = H P H^T + R, H rows hxr, hzr
        PHx = [Pn[i][0] * hxr[0] + Pn[i][1] * hxr[1] + Pn[i][2] * hxr[2] + Pn[i][3] * hxr[3] for i in range(4)]
        PHz = [Pn[i][0] * hzr[0] + Pn[i][1] * hzr[1] + Pn[i][2] * hzr[2] + Pn[i][3] * hzr[3] for i in range(4)]
        r = self.force_noise ** 2 + (self.force_rel * (yx * yx + yz * yz) ** 0.5) ** 2
        s11 = hxr[0] * PHx[0] + hxr[1] * PHx[1] + hxr[2] * PHx[2] + hxr[3] * PHx[3] + r
        s12 = hzr[0] * PHx[0] + hzr[1] * PHx[1] + hzr[2] * PHx[2] + hzr[3] * PHx[3]
        s22 = hzr[0] * PHz[0] + hzr[1] * PHz[1] + hzr[2] * PHz[2] + hzr[3] * PHz[3] + r
        det = s11 * s22 - s12 * s12
        ex, ez = yx - base[2], yz - base[3]
        if det > 1e-12:
            i11, i12, i22 = s22 / det, -s12 / det, s11 / det
            nis = ex * (i11 * ex + i12 * ez) + ez * (i12 * ex + i22 * ez)
            if nis < self.gate:
                kx = [PHx[i] * i11 + PHz[i] * i12 for i in range(4)]
                kz = [PHx[i] * i12 + PHz[i] * i22 for i in range(4)]
                x0 += kx[0] * ex + kz[0] * ez
                x1 += kx[1] * ex + kz[1] * ez
                x2 += kx[2] * ex + kz[2] * ez
                x3 += kx[3] * ex + kz[3] * ez
                # P = P - K H P = P - kx PHx^T - kz PHz^T
                for i in range(4):
                    row = Pn[i]
                    for j in range(4):
                        row[j] -= kx[i] * PHx[j] + kz[i] * PHz[j]
            else:
                self.rejected += 1
        self.P = Pn
        self.x = [_wrap(x0), _wrap(x1), x2, x3]
        return _wrap(x1 - q), x3 - w
