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

from ..angles import wrap_angle

GRAVITY = 9.81
TWO_PI = 2.0 * math.pi



class LoadEstimator:
    """Extended Kalman filter for the chain and free rod of a nunchaku held by its other rod.

    Parameters are the nominal model (kg, m) and the filter's noise levels: ``accel_noise`` is the
    standard deviation of unmodelled angular acceleration (chain bending, friction) in rad/s^2,
    ``force_noise`` + ``force_rel`` * |pull| that of the pull measurement per axis in N, ``gate``
    the largest normalised innovation squared that is accepted.
    """

    def __init__(self, m_hand: float = 0.35, m_held: float = 0.2, m_chain: float = 0.06, l_chain: float = 0.12,
                 m_rod: float = 0.2, l_rod: float = 0.30, damping: float = 0.0005, accel_noise: float = 40.0,
                 force_noise: float = 0.6, force_rel: float = 0.08, gate: float = 50.0, jacobian_every: int = 2,
                 rod_accel_noise: float | None = None):
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
        self.jacobian_every = jacobian_every
        self.rod_accel_noise = rod_accel_noise
        self._nominal_masses = (m_held, m_chain, m_rod)
        self._constants()
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
        self.P = (v, 0.9 * v, 0.0, 0.0, v, 0.0, 0.0, 4.0, 0.0, 4.0)
        self.pull = (0.0, 0.0)
        self.rejected = 0
        self._jac = None
        self._n = 0

    def weigh(self, load: float, nominal: float = 0.46) -> float:
        """Scale the nunchaku's masses to a measured static ``load`` [N] of the whole nunchaku.

        The robot weighs what it holds: at rest the wrist carries the hand, the held rod and the
        free part; ``load`` is that minus the hand's own weight. Rods and chain are assumed to scale
        alike (one material); returns the scale applied to the nominal masses.
        """
        scale = min(max(load / (GRAVITY * nominal), 0.5), 2.0)
        self.m_held = self._nominal_masses[0] * scale
        self.m_chain = self._nominal_masses[1] * scale
        self.m_rod = self._nominal_masses[2] * scale
        self._constants()
        return scale

    @property
    def chain_angle(self) -> float:
        """Estimated world angle of the chain [rad]."""
        return self.x[0]

    def _constants(self) -> None:
        l1, mc, m2, d = self.l_chain, 0.5 * self.m_chain, self.m_rod, 0.5 * self.l_rod
        m11 = (mc + m2) * l1 * l1
        m22 = m2 * d * d + m2 * self.l_rod * self.l_rod / 12.0
        self._k = (l1, mc, m2, d, m11, m22, m2 * l1 * d, (mc + m2) * l1, m2 * d, self.damping)

    def _dyn(self, t1: float, t2: float, w1: float, w2: float, gx: float, gz: float, wh: float):
        """Angular accelerations of chain and rod, and their pull on the pivot."""
        l1, mc, m2, d, m11, m22, mld, k1, k2, b = self._k
        s1, c1 = math.sin(t1), math.cos(t1)
        s2, c2 = math.sin(t2), math.cos(t2)
        sd = s1 * c2 - c1 * s2
        m12 = mld * (c1 * c2 + s1 * s2)
        r1 = k1 * (gx * c1 + gz * s1) - mld * sd * w2 * w2 - b * (2.0 * w1 - wh - w2)
        r2 = k2 * (gx * c2 + gz * s2) + mld * sd * w1 * w1 - b * (w2 - w1)
        det = m11 * m22 - m12 * m12
        a1 = (m22 * r1 - m12 * r2) / det
        a2 = (m11 * r2 - m12 * r1) / det
        w1s, w2s = w1 * w1, w2 * w2
        apx = l1 * (a1 * c1 - w1s * s1)
        apz = l1 * (a1 * s1 + w1s * c1)
        fx = (mc + m2) * (gx - apx) - m2 * d * (a2 * c2 - w2s * s2)
        fz = (mc + m2) * (gz - apz) - m2 * d * (a2 * s2 + w2s * c2)
        if fx * s1 - fz * c1 < 0.0:
            return (gx * c1 + gz * s1) / l1, 0.0, mc * gx, mc * gz
        return a1, a2, fx + mc * gx, fz + mc * gz

    # One function on purpose: a filter step run every millisecond on scalars, where calls would cost
    # more than the arithmetic.
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
        # Jacobian rows of (a1, a2, hx, hz) w.r.t. the state, by forward differences; it changes
        # slowly at 1 kHz, so it is refreshed every ``jacobian_every`` updates
        if self._jac is None or self._n % self.jacobian_every == 0:
            jac = []
            for k, eps in ((0, 1e-4), (1, 1e-4), (2, 1e-3), (3, 1e-3)):
                xs = [x0, x1, x2, x3]
                xs[k] += eps
                r = dyn(xs[0], xs[1], xs[2], xs[3], gx, gz, w)
                jac.append(((r[0] - base[0]) / eps, (r[1] - base[1]) / eps, (r[2] - base[2]) / eps,
                            (r[3] - base[3]) / eps))
            self._jac = ([j[0] for j in jac], [j[1] for j in jac], [j[2] for j in jac], [j[3] for j in jac])
        self._n += 1
        ja1, ja2, hxr, hzr = self._jac
        # covariance, symmetric, stored as its upper triangle
        p00, p01, p02, p03, p11, p12, p13, p22, p23, p33 = self.P
        u0, u1, u2, u3 = ja1
        v0, v1, v2, v3 = ja2
        # A = F P with F = I + dt [[0 0 1 0], [0 0 0 1], ja1, ja2]
        a00, a01, a02, a03 = p00 + dt * p02, p01 + dt * p12, p02 + dt * p22, p03 + dt * p23
        a10, a11, a12, a13 = p01 + dt * p03, p11 + dt * p13, p12 + dt * p23, p13 + dt * p33
        a20 = p02 + dt * (u0 * p00 + u1 * p01 + u2 * p02 + u3 * p03)
        a21 = p12 + dt * (u0 * p01 + u1 * p11 + u2 * p12 + u3 * p13)
        a22 = p22 + dt * (u0 * p02 + u1 * p12 + u2 * p22 + u3 * p23)
        a23 = p23 + dt * (u0 * p03 + u1 * p13 + u2 * p23 + u3 * p33)
        a30 = p03 + dt * (v0 * p00 + v1 * p01 + v2 * p02 + v3 * p03)
        a31 = p13 + dt * (v0 * p01 + v1 * p11 + v2 * p12 + v3 * p13)
        a32 = p23 + dt * (v0 * p02 + v1 * p12 + v2 * p22 + v3 * p23)
        a33 = p33 + dt * (v0 * p03 + v1 * p13 + v2 * p23 + v3 * p33)
        # P = A F^T + Q
        qn = (self.accel_noise * dt) ** 2
        qr = qn if self.rod_accel_noise is None else (self.rod_accel_noise * dt) ** 2
        n00 = a00 + dt * a02
        n01 = a01 + dt * a03
        n02 = a02 + dt * (u0 * a00 + u1 * a01 + u2 * a02 + u3 * a03)
        n03 = a03 + dt * (v0 * a00 + v1 * a01 + v2 * a02 + v3 * a03)
        n11 = a11 + dt * a13
        n12 = a12 + dt * (u0 * a10 + u1 * a11 + u2 * a12 + u3 * a13)
        n13 = a13 + dt * (v0 * a10 + v1 * a11 + v2 * a12 + v3 * a13)
        n22 = a22 + dt * (u0 * a20 + u1 * a21 + u2 * a22 + u3 * a23) + qn
        n23 = a23 + dt * (v0 * a20 + v1 * a21 + v2 * a22 + v3 * a23)
        n33 = a33 + dt * (v0 * a30 + v1 * a31 + v2 * a32 + v3 * a33) + qr
        # measurement update: H rows hxr, hzr;  S = H P H^T + R
        h0, h1, h2, h3 = hxr
        g0, g1, g2, g3 = hzr
        bx0 = n00 * h0 + n01 * h1 + n02 * h2 + n03 * h3
        bx1 = n01 * h0 + n11 * h1 + n12 * h2 + n13 * h3
        bx2 = n02 * h0 + n12 * h1 + n22 * h2 + n23 * h3
        bx3 = n03 * h0 + n13 * h1 + n23 * h2 + n33 * h3
        bz0 = n00 * g0 + n01 * g1 + n02 * g2 + n03 * g3
        bz1 = n01 * g0 + n11 * g1 + n12 * g2 + n13 * g3
        bz2 = n02 * g0 + n12 * g1 + n22 * g2 + n23 * g3
        bz3 = n03 * g0 + n13 * g1 + n23 * g2 + n33 * g3
        r = self.force_noise ** 2 + self.force_rel ** 2 * (yx * yx + yz * yz)
        s11 = h0 * bx0 + h1 * bx1 + h2 * bx2 + h3 * bx3 + r
        s12 = g0 * bx0 + g1 * bx1 + g2 * bx2 + g3 * bx3
        s22 = g0 * bz0 + g1 * bz1 + g2 * bz2 + g3 * bz3 + r
        det = s11 * s22 - s12 * s12
        ex, ez = yx - base[2], yz - base[3]
        if det > 1e-12:
            i11, i12, i22 = s22 / det, -s12 / det, s11 / det
            nis = ex * (i11 * ex + i12 * ez) + ez * (i12 * ex + i22 * ez)
            if nis < self.gate:
                kx0, kz0 = bx0 * i11 + bz0 * i12, bx0 * i12 + bz0 * i22
                kx1, kz1 = bx1 * i11 + bz1 * i12, bx1 * i12 + bz1 * i22
                kx2, kz2 = bx2 * i11 + bz2 * i12, bx2 * i12 + bz2 * i22
                kx3, kz3 = bx3 * i11 + bz3 * i12, bx3 * i12 + bz3 * i22
                x0 += kx0 * ex + kz0 * ez
                x1 += kx1 * ex + kz1 * ez
                x2 += kx2 * ex + kz2 * ez
                x3 += kx3 * ex + kz3 * ez
                # P -= K H P = kx bx^T + kz bz^T
                n00 -= kx0 * bx0 + kz0 * bz0
                n01 -= kx0 * bx1 + kz0 * bz1
                n02 -= kx0 * bx2 + kz0 * bz2
                n03 -= kx0 * bx3 + kz0 * bz3
                n11 -= kx1 * bx1 + kz1 * bz1
                n12 -= kx1 * bx2 + kz1 * bz2
                n13 -= kx1 * bx3 + kz1 * bz3
                n22 -= kx2 * bx2 + kz2 * bz2
                n23 -= kx2 * bx3 + kz2 * bz3
                n33 -= kx3 * bx3 + kz3 * bz3
            else:
                self.rejected += 1
        self.P = (n00, n01, n02, n03, n11, n12, n13, n22, n23, n33)
        self.x = [wrap_angle(x0), wrap_angle(x1), x2, x3]
        return wrap_angle(x1 - q), x3 - w
