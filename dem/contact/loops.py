"""The compiled time-step loop for sphere scenes: one loop per (dimension, laws).

``stepper(dim, law_pp, law_pw)`` returns a kernel that advances the scene by up to
``n_steps`` velocity Verlet steps inside one call. The dimension and the two contact
laws (sphere-sphere, sphere-wall) are compile-time constants of the returned kernel, so
a 2D scene runs 2D code and a scene runs only the laws it uses. Kernels are memoised.

One step, in this order (the ``Simulation.run`` contract):

1. half kick and drift of free bodies (``v += dt/2 F/m``, ``x += dt v``, angle or
   quaternion update); fixed bodies drift at their prescribed velocity;
2. if a body is now more than ``skin / 2`` from where the neighbour list was built:
   stop with status ``REBUILD``; Python rebuilds the list and calls again with
   ``resume=True``, which finishes this step from 3;
3. sphere-sphere contacts (parallel over pairs): overlap, relative velocity at the
   contact point, law -> per-pair force and the two torques;
4. sphere-wall contacts (parallel over pairs), likewise;
5. per body (parallel over bodies, pairs visited in a fixed order): sum of contact
   forces, gravity, local damping, second half kick.

Per-pair results are gathered per body in a fixed order, never scattered with atomics,
so the result does not depend on the number of threads. ``touch[k]`` marks the pairs in
contact at the last force evaluation; only those are gathered.
"""

import math

import numba
import numpy as np

from .._jit import kernel
from .laws import law_hertz_mindlin, law_linear

OK, REBUILD, NONFINITE, OVERLAP = 0, 1, 2, 3

_STEPPERS = {}


def stepper(dim, law_pp, law_pw):
    """The compiled multi-step kernel for ``dim`` (2 or 3) and two law codes.

    ``law_pp``/``law_pw`` are law codes (a law class's ``code``: 0 linear, 1
    Hertz-Mindlin). Only integers are captured, so the kernel caches on disk; the law
    branches not taken are pruned at compile time.
    """
    key = (int(dim), int(law_pp), int(law_pw))
    if key in _STEPPERS:
        return _STEPPERS[key]
    DIM, PP, PW = key

    @kernel(parallel=True)
    def run_steps(n_steps, prime, resume, dt, gravity, damping, skin, overlap_limit,
                  pos, vel, rot, ang_vel, force, torque, radius, mass, inv_mass,
                  inv_inertia, is_fixed, normal, mat_id, pos_ref, hmat,
                  pairs, img, touch, hist, fpair, tpi, tpj, pstart, jstart, jlist,
                  params_pp, wpairs, whist, wforce, wtorque, wstart, params_pw,
                  status_out, work_out):
        """Advance ``n_steps``; returns the number of completed steps.

        ``prime`` = True computes forces at the current state without moving anything
        (tangential springs are not advanced). ``resume`` = True finishes a step whose
        drift was done by the previous call (which stopped with ``REBUILD``).
        ``status_out`` (4,) int64 receives (code, i, j, 0); ``work_out`` (1,)
        accumulates the work of walls on bodies [J].
        """
        n = pos.shape[0]
        m = pairs.shape[0]
        mw = wpairs.shape[0]
        status_out[0] = OK
        done = 0
        half = 0.5 * dt
        hdt = 0.0 if prime else dt
        n_iter = 1 if prime else n_steps
        for it in range(n_iter):
            if not prime and not (resume and it == 0):
                # ---- 1. half kick + drift
                maxd2 = 0.0
                for b in numba.prange(n):
                    if is_fixed[b]:
                        s2 = 0.0
                        for a in range(DIM):
                            pos[b, a] += dt * vel[b, a]
                            dx = pos[b, a] - pos_ref[b, a]
                            s2 += dx * dx
                        maxd2 = max(maxd2, s2)
                        continue
                    s2 = 0.0
                    for a in range(DIM):
                        vel[b, a] += half * force[b, a] * inv_mass[b]
                        pos[b, a] += dt * vel[b, a]
                        dx = pos[b, a] - pos_ref[b, a]
                        s2 += dx * dx
                    maxd2 = max(maxd2, s2)
                    if DIM == 2:
                        ang_vel[b, 0] += half * torque[b, 0] * inv_inertia[b, 0]
                        rot[b, 0] += dt * ang_vel[b, 0]
                    else:
                        wx = ang_vel[b, 0] + half * torque[b, 0] * inv_inertia[b, 0]
                        wy = ang_vel[b, 1] + half * torque[b, 1] * inv_inertia[b, 1]
                        wz = ang_vel[b, 2] + half * torque[b, 2] * inv_inertia[b, 2]
                        ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2] = wx, wy, wz
                        # rotation by |w| dt about w: unit quaternion with half-angle
                        # atan(|w| dt / 2) (the exponential map to O((|w| dt)^3))
                        hx, hy, hz = half * wx, half * wy, half * wz
                        c = 1.0 / math.sqrt(1.0 + hx * hx + hy * hy + hz * hz)
                        rw, rx, ry, rz = c, c * hx, c * hy, c * hz
                        qw, qx, qy, qz = rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3]
                        rot[b, 0] = rw * qw - rx * qx - ry * qy - rz * qz
                        rot[b, 1] = rw * qx + rx * qw + ry * qz - rz * qy
                        rot[b, 2] = rw * qy - rx * qz + ry * qw + rz * qx
                        rot[b, 3] = rw * qz + rx * qy - ry * qx + rz * qw
                # ---- 2. the neighbour list must hold for the new positions
                if 4.0 * maxd2 > skin * skin:
                    status_out[0] = REBUILD
                    return done
            # ---- 3. sphere-sphere contacts
            for k in numba.prange(m):
                i = pairs[k, 0]
                j = pairs[k, 1]
                dx = pos[j, 0] - pos[i, 0]
                dy = pos[j, 1] - pos[i, 1]
                dz = pos[j, 2] - pos[i, 2] if DIM == 3 else 0.0
                if img[k, 0] != 0 or img[k, 1] != 0 or (DIM == 3 and img[k, DIM - 1] != 0):
                    for a in range(DIM):
                        sh = 0.0
                        for c in range(DIM):
                            sh += hmat[a, c] * img[k, c]
                        if a == 0:
                            dx += sh
                        elif a == 1:
                            dy += sh
                        else:
                            dz += sh
                ri = radius[i]
                rj = radius[j]
                dist2 = dx * dx + dy * dy + dz * dz
                cut = ri + rj
                if dist2 >= cut * cut:
                    if touch[k]:  # the contact opened: its history ends
                        touch[k] = 0
                        hist[k, 0] = 0.0
                        hist[k, 1] = 0.0
                        hist[k, 2] = 0.0
                    continue
                touch[k] = 1
                dist = math.sqrt(dist2)
                inv = 1.0 / dist
                nx, ny, nz = dx * inv, dy * inv, dz * inv
                ov = cut - dist
                if ov > overlap_limit * min(ri, rj):
                    status_out[0] = OVERLAP
                    status_out[1] = i
                    status_out[2] = j
                li = ri - 0.5 * ov  # lever arms from each centre to the contact point
                lj = rj - 0.5 * ov
                # relative velocity of j w.r.t. i at the contact point
                if DIM == 2:
                    wi, wj = ang_vel[i, 0], ang_vel[j, 0]
                    vx = vel[j, 0] - vel[i, 0] + (wj * lj + wi * li) * ny
                    vy = vel[j, 1] - vel[i, 1] - (wj * lj + wi * li) * nx
                    vz = 0.0
                else:
                    # w_j x (-lj n) - w_i x (li n) = -(lj w_j + li w_i) x n
                    sx = lj * ang_vel[j, 0] + li * ang_vel[i, 0]
                    sy = lj * ang_vel[j, 1] + li * ang_vel[i, 1]
                    sz = lj * ang_vel[j, 2] + li * ang_vel[i, 2]
                    vx = vel[j, 0] - vel[i, 0] - (sy * nz - sz * ny)
                    vy = vel[j, 1] - vel[i, 1] - (sz * nx - sx * nz)
                    vz = vel[j, 2] - vel[i, 2] - (sx * ny - sy * nx)
                r_eff = ri * rj / (ri + rj)
                m_eff = 1.0 / (inv_mass[i] + inv_mass[j])
                ma, mb = mat_id[i], mat_id[j]
                # one branch per law code; PP is a constant, the others are pruned
                if PP == 0:
                    fx, fy, fz = law_linear(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff,
                                            params_pp, ma, mb, hist, k, hdt)
                else:
                    fx, fy, fz = law_hertz_mindlin(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff,
                                                   params_pp, ma, mb, hist, k, hdt)
                fpair[k, 0] = fx
                fpair[k, 1] = fy
                if DIM == 2:
                    t = nx * fy - ny * fx  # n x f
                    tpi[k, 0] = -li * t
                    tpj[k, 0] = -lj * t
                else:
                    fpair[k, 2] = fz
                    tx = ny * fz - nz * fy
                    ty = nz * fx - nx * fz
                    tz = nx * fy - ny * fx
                    tpi[k, 0], tpi[k, 1], tpi[k, 2] = -li * tx, -li * ty, -li * tz
                    tpj[k, 0], tpj[k, 1], tpj[k, 2] = -lj * tx, -lj * ty, -lj * tz
            # ---- 4. sphere-wall contacts (home body: sphere; normal points into the wall)
            work = 0.0
            for k in numba.prange(mw):
                i = wpairs[k, 0]
                w = wpairs[k, 1]
                nx = -normal[w, 0]
                ny = -normal[w, 1]
                nz = -normal[w, 2] if DIM == 3 else 0.0
                gap = (pos[i, 0] - pos[w, 0]) * normal[w, 0] + (pos[i, 1] - pos[w, 1]) * normal[w, 1]
                if DIM == 3:
                    gap += (pos[i, 2] - pos[w, 2]) * normal[w, 2]
                ri = radius[i]
                ov = ri - gap
                if ov <= 0.0:
                    whist[k, 0] = 0.0
                    whist[k, 1] = 0.0
                    whist[k, 2] = 0.0
                    for a in range(DIM):
                        wforce[k, a] = 0.0
                    for a in range(wtorque.shape[1]):
                        wtorque[k, a] = 0.0
                    continue
                if ov > overlap_limit * ri:
                    status_out[0] = OVERLAP
                    status_out[1] = i
                    status_out[2] = w
                li = ri - 0.5 * ov
                if DIM == 2:
                    wi = ang_vel[i, 0]
                    vx = vel[w, 0] - vel[i, 0] + wi * li * ny
                    vy = vel[w, 1] - vel[i, 1] - wi * li * nx
                    vz = 0.0
                else:
                    sx, sy, sz = li * ang_vel[i, 0], li * ang_vel[i, 1], li * ang_vel[i, 2]
                    vx = vel[w, 0] - vel[i, 0] - (sy * nz - sz * ny)
                    vy = vel[w, 1] - vel[i, 1] - (sz * nx - sx * nz)
                    vz = vel[w, 2] - vel[i, 2] - (sx * ny - sy * nx)
                m_eff = 1.0 / inv_mass[i]
                ma, mb = mat_id[i], mat_id[w]
                if PW == 0:
                    fx, fy, fz = law_linear(ov, nx, ny, nz, vx, vy, vz, ri, m_eff,
                                            params_pw, ma, mb, whist, k, hdt)
                else:
                    fx, fy, fz = law_hertz_mindlin(ov, nx, ny, nz, vx, vy, vz, ri, m_eff,
                                                   params_pw, ma, mb, whist, k, hdt)
                # force on the sphere is -f; torque li n x (-f)
                wforce[k, 0] = -fx
                wforce[k, 1] = -fy
                if DIM == 2:
                    wtorque[k, 0] = -li * (nx * fy - ny * fx)
                    work -= fx * vel[w, 0] + fy * vel[w, 1]
                else:
                    wforce[k, 2] = -fz
                    wtorque[k, 0] = -li * (ny * fz - nz * fy)
                    wtorque[k, 1] = -li * (nz * fx - nx * fz)
                    wtorque[k, 2] = -li * (nx * fy - ny * fx)
                    work -= fx * vel[w, 0] + fy * vel[w, 1] + fz * vel[w, 2]
            if not prime:
                work_out[0] += work * dt
            # ---- 5. gather, gravity, damping, second half kick
            for b in numba.prange(n):
                if is_fixed[b]:
                    continue
                fx = 0.0
                fy = 0.0
                fz = 0.0
                tx = 0.0
                ty = 0.0
                tz = 0.0
                for k in range(pstart[b], pstart[b + 1]):
                    if not touch[k]:
                        continue
                    fx -= fpair[k, 0]
                    fy -= fpair[k, 1]
                    tx += tpi[k, 0]
                    if DIM == 3:
                        fz -= fpair[k, 2]
                        ty += tpi[k, 1]
                        tz += tpi[k, 2]
                for q in range(jstart[b], jstart[b + 1]):
                    k = jlist[q]
                    if not touch[k]:
                        continue
                    fx += fpair[k, 0]
                    fy += fpair[k, 1]
                    tx += tpj[k, 0]
                    if DIM == 3:
                        fz += fpair[k, 2]
                        ty += tpj[k, 1]
                        tz += tpj[k, 2]
                for k in range(wstart[b], wstart[b + 1]):
                    fx += wforce[k, 0]
                    fy += wforce[k, 1]
                    tx += wtorque[k, 0]
                    if DIM == 3:
                        fz += wforce[k, 2]
                        ty += wtorque[k, 1]
                        tz += wtorque[k, 2]
                mb = mass[b]
                fx += mb * gravity[0]
                fy += mb * gravity[1]
                if DIM == 3:
                    fz += mb * gravity[2]
                if damping > 0.0:  # Cundall local damping: oppose the velocity sign
                    fx -= damping * abs(fx) * np.sign(vel[b, 0])
                    fy -= damping * abs(fy) * np.sign(vel[b, 1])
                    if DIM == 3:
                        fz -= damping * abs(fz) * np.sign(vel[b, 2])
                    tx -= damping * abs(tx) * np.sign(ang_vel[b, 0])
                    if DIM == 3:
                        ty -= damping * abs(ty) * np.sign(ang_vel[b, 1])
                        tz -= damping * abs(tz) * np.sign(ang_vel[b, 2])
                if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz)):
                    status_out[0] = NONFINITE
                    status_out[1] = b
                force[b, 0] = fx
                force[b, 1] = fy
                torque[b, 0] = tx
                if DIM == 3:
                    force[b, 2] = fz
                    torque[b, 1] = ty
                    torque[b, 2] = tz
                if not prime:
                    vel[b, 0] += half * fx * inv_mass[b]
                    vel[b, 1] += half * fy * inv_mass[b]
                    ang_vel[b, 0] += half * tx * inv_inertia[b, 0]
                    if DIM == 3:
                        vel[b, 2] += half * fz * inv_mass[b]
                        ang_vel[b, 1] += half * ty * inv_inertia[b, 1]
                        ang_vel[b, 2] += half * tz * inv_inertia[b, 2]
            if status_out[0] != OK:
                return done
            done += 1 if not prime else 0
        return done

    _STEPPERS[key] = run_steps
    return run_steps
