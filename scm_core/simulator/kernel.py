"""The SWT time loop (numba): z-buffer, implicit vertical step, deformation, outputs.

Per step (DESIGN.md section 3): carriage and wheel angle advance by their imposed velocities; the
z-buffer of the wheel is built; the axle height is found by a backward-Euler step of the vertical
rig dynamics m z'' = Fz(z, z') - W, solved as a root of
    G(z) = m (z - z_n - dt v_n) / dt^2 + W - Fz(z) = 0
with the contact, footprint (b_eff) and border taper evaluated at the trial height (safeguarded
Newton inside a bracket). At SWT speeds the soil acts on the vertical motion as a very stiff damper
(elastic unloading modulus K times the footprint area), which an explicit step resolves only below a
millisecond; the implicit step is stable at 10-20 ms. Then the nodes are updated and the soil flows.

Flags and small integers passed to jitted callees are np.bool_ / np.int64 values, not literals:
numba compiles a separate copy of a callee for every literal argument (with literals, and a
parallel batch loop, a cold compile took 49 s; now about 20 s).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from .contact import (
    N_RES,
    R_DFZ,
    R_FX,
    R_FY,
    R_FZ,
    R_KSTAR,
    R_NCONTACT,
    R_T,
    build_patches,
    evaluate_contact,
)
from .cycles import cycles
from .deformation import bow_wave, commit_contact, heap_passive_pressure
from .erosion import erode, erosion_scratch
from .flow import flow_and_deposit
from .geometry import tip_circle, wheel_envelope
from .layout import (
    P_B,
    P_BULLDOZE,
    P_DT,
    P_DURATION,
    P_DX,
    P_DYDX,
    P_EROSIONEVERY,
    P_GAMMA,
    P_HG,
    P_K,
    P_KC,
    P_KPHI,
    P_MARGIN,
    P_MASS,
    P_MAXSINK,
    P_NGROUSERS,
    P_OFF_F,
    P_OFF_T,
    P_OFF_Z,
    P_OMEGA,
    P_OUTEVERY,
    P_R,
    P_SETTLE,
    P_TANPHI,
    P_TANREPOSE,
    P_TG,
    P_V,
    P_VLAT,
    P_W,
    P_ZDATUM,
    STATUS_BOTTOMED_OUT,
    STATUS_NONPOSITIVE_STIFFNESS,
    STATUS_OK,
    STATUS_UNSTABLE,
)
from .outputs import N_SERIES, S_F, S_T, record_step, settled
from .side import side_force
from .state import Columns, FlowScratch, Ground, Marks, Patches, Window

# diagnostics vector
D_STEPS = 0
D_NODE_STEPS = 1  # sum over steps of loaded nodes
D_PATCH_STEPS = 2
D_ITERATIONS = 3  # contact evaluations in the vertical solves
D_COMPACTED = 4  # m^3
D_VOLUME0 = 5  # m^3
D_VOLUME1 = 6
D_DY = 7
D_X0 = 8
D_JW0 = 9
D_NYW = 10
D_EROSION_VISITS = 11
D_SPILLED = 12  # m^3 of flowing soil that left the grid
# cycle-counter ticks per phase of the step (shares of the run's time; see cycles.py)
D_CYC_GEOMETRY = 13  # wheel envelope and contact patches
D_CYC_SOLVE = 14  # vertical solve (contact evaluations)
D_CYC_COMMIT = 15  # node update
D_CYC_FLOW = 16  # flow fields and deposits
D_CYC_EROSION = 17
D_HEAP_H = 18  # the bow wave's height at the last step [m] (bulk_density > 0)
D_HEAP_F = 19  # the horizontal force of its own wedge on the rim at the last step [N]
N_DIAG = 20

# convergence of the axle height [m]: where G jumps (a patch entering contact carries its damping
# stress at once) the root is the jump, bracketed to the height change whose inertia m dz / dt^2
# is G_TOL W (g dt^2 / 1000: 3.9 um at the paper's 20 ms, 0.08 nm at 0.3 ms, where 1 um of axle
# height is 31 N of a 26 N wheel's balance), at most Z_TOL (1 um instead cost 0.3-1.7 more
# evaluations per step; physics_drift: no steady mean moved by more than 0.5 % of W, 0.11 mm)
Z_TOL = 1e-5
MAX_ITER = 80
FREEZE_AFTER = 1  # evaluations before the footprint is frozen within a step
# residual of the force balance, relative to W (1e-4 moved no steady mean by more than 0.2 % of W
# and 0.02 mm against 1e-3: benchmarks/physics_drift.py, issue 42)
G_TOL = 1e-3
OUTER_TOL = 0.05  # footprint re-solves while its change moves the balance by more (x W)
# footprint solves per step: where the root lies at a column's entry into contact, the footprint
# flips between two states from solve to solve (the taper's mean-one normalisation over the loaded
# nodes jumps by that column's share), so more solves only alternate; the last one is balanced
MAX_OUTER = 2
X_PAD = 0.02  # m of untouched soil before the start and after the end of the run
# fractions of the averaging window of F and T at which a run with a steady tolerance may stop
SETTLE_CHECKS = (0.25, 0.5, 0.75)


@njit(cache=True)
def grid_shape(prm: np.ndarray):
    """(nx, ny, nyw, n_margin, dy, x0) of the DEM for these parameters: a steered wheel's
    grid is wider by the rows it slides across (:func:`lateral_rows`)."""
    dx = prm[P_DX]
    b = prm[P_B]
    nyw = max(1, int(round(b / (prm[P_DYDX] * dx))))
    dy = b / nyw
    n_margin = int(math.ceil(prm[P_MARGIN] / dy))
    ny = nyw + 2 * n_margin + lateral_rows(prm, dy)
    r_out = prm[P_R] + prm[P_HG]
    x0 = -(r_out + X_PAD)
    x1 = prm[P_V] * prm[P_DURATION] + r_out + X_PAD
    nx = int(math.ceil((x1 - x0) / dx)) + 2
    return nx, ny, nyw, n_margin, dy, x0


@njit(cache=True)
def lateral_rows(prm: np.ndarray, dy: float) -> int:
    """Rows a steered wheel slides across over the run, |v_y| duration / dy (0 straight)."""
    if prm[P_VLAT] == 0.0:
        return 0
    return int(math.ceil(abs(prm[P_VLAT]) * prm[P_DURATION] / dy)) + 1


@njit(cache=True)
def rows_under(j_start: int, y: float, dy: float, last: int) -> int:
    """The first row under a wheel that has slid by ``y`` [m] along its axle since it stood
    on row ``j_start`` (at most ``last``)."""
    if y == 0.0:
        return j_start
    return min(max(j_start + int(round(y / dy)), 0), last)


@njit(cache=True)
def first_row(prm: np.ndarray, n_margin: int, dy: float) -> int:
    """The first row under the wheel at the start: past the margin, and past the rows it will
    slide across when it slides toward -y."""
    return n_margin + (lateral_rows(prm, dy) if prm[P_VLAT] < 0.0 else 0)


#: this step's vertical problem: the last axle height zn, the predicted zpred = zn + dt vn, the
#: free-fall height z_free and the last contact ztop (the bracket), m / dt^2 (c_in), the load W,
#: the time step dt and the height tolerance z_tol
Vertical = namedtuple("Vertical", ["zn", "zpred", "z_free", "ztop", "c_in", "W", "dt", "z_tol"])
#: what an evaluation of the contact reads: the packed parameters, the step's patch count, the
#: grid (dx, dy, rows under the wheel), work = (patches, columns, res), the diagnostics and the
#: bow wave's surcharge on the wheel's front [Pa]
ContactCall = namedtuple(
    "ContactCall", ["prm", "npatch", "dx", "dy", "nyw", "work", "diag", "surcharge"]
)


@njit(cache=True)
def _evaluate(z, zn, dt, call, freeze):
    """Contact forces at axle height z (vertical velocity from the backward-Euler step from zn
    over dt); ``call.work`` = (patches, columns, res)."""
    patches, cols, res = call.work
    evaluate_contact(
        z, (z - zn) / dt, call.prm, call.npatch, patches, cols, call.dx, call.dy, call.nyw, res,
        freeze, call.surcharge,
    )  # fmt: skip
    call.diag[D_ITERATIONS] += 1
    return res[R_FZ]


@njit(cache=True)
def _solve_vertical(zn, vn, prm, npatch, ztop, dx, dy, nyw, work, diag, surcharge):
    """Backward-Euler axle height for this step; leaves the contact state evaluated there.

    Root of G(z) = m (z - z_n - dt v_n) / dt^2 + W - Fz(z) in the bracket [free fall, last
    contact]: Newton, regula falsi (Illinois) when Newton stalls at a kink, bisection when the
    bracket does not halve. After FREEZE_AFTER evaluations the footprint quantities are frozen
    (see evaluate_contact) and the result is re-evaluated on its own footprint; while that moves
    G by more than OUTER_TOL * W (a footprint that changes a lot within the step, e.g. grousers
    on a very stiff soil) the solve is repeated once on the new footprint (MAX_OUTER), so the
    forces reported balance the dynamics.
    """
    dt = prm[P_DT]
    m = prm[P_MASS]
    W = prm[P_W]
    c_in = m / (dt * dt)
    zpred = zn + dt * vn
    z_free = zpred - W / c_in  # free fall: no soil force
    call = ContactCall(prm, npatch, dx, dy, nyw, work, diag, surcharge)
    if z_free >= ztop:  # the wheel touches nothing at the free-fall height
        _evaluate(z_free, zn, dt, call, np.bool_(False))
        return z_free, True
    z = min(max(zpred, z_free), max(ztop, z_free))
    z_tol = min(Z_TOL, G_TOL * W / c_in)  # the height change whose inertia is G_TOL W
    vert = Vertical(zn, zpred, z_free, ztop, c_in, W, dt, z_tol)
    converged = False
    g_known = np.nan  # G at z on the current footprint, when the last evaluation was there
    for outer in range(MAX_OUTER):
        z, converged, g, at_z, unfrozen = _newton(
            z, vert, call, FREEZE_AFTER if outer == 0 else 0, g_known
        )
        if not converged or outer == MAX_OUTER - 1:
            # the footprint keeps changing (e.g. k_c << 0): end on the balanced frozen solve
            # (already evaluated when the solve's last evaluation was at z)
            if not at_z:
                _evaluate(z, zn, dt, call, np.bool_(True))
            break
        if not (at_z and unfrozen):  # else the last evaluation was this footprint check
            g = c_in * (z - zpred) + W - _evaluate(z, zn, dt, call, np.bool_(False))
        if abs(g) < OUTER_TOL * W:
            break
        g_known = g  # the next solve starts here, frozen on this footprint: the same G
    return z, converged


@njit(cache=True)
def _newton(z, vert, call, freeze_after, g_start):
    """Safeguarded Newton for G(z) = 0 from ``z``; frozen footprint after ``freeze_after``
    evaluations; converged when |G| < G_TOL W or the bracket or step is below ``vert.z_tol``
    [m]. ``g_start``: G at ``z`` when the contact state is already evaluated there on
    the footprint this solve uses (NaN: evaluate it). Returns (z, converged, G, at_z,
    unfrozen): G of the last evaluation, whether that evaluation was at the returned z (the
    contact state is then the solution's), and whether it was unfrozen."""
    zn, zpred, z_free, ztop, c_in, W, dt, z_tol = vert
    lo = z_free
    g_lo = np.nan  # G(z_free) < 0, not evaluated: regula falsi waits until lo has a value
    hi = max(ztop, z_free)
    g_hi = c_in * (hi - zpred) + W  # no contact at ztop
    g_prev = np.inf
    z_prev = z
    side = 0
    width_2ago = np.inf
    width_1ago = hi - lo
    g = np.nan
    frozen = True
    for it in range(MAX_ITER):
        frozen = it >= freeze_after
        if it == 0 and np.isfinite(g_start):
            g = g_start
        else:
            g = c_in * (z - zpred) + W - _evaluate(z, zn, dt, call, frozen)
        if abs(g) < G_TOL * W:
            return z, True, g, True, not frozen
        if g > 0.0:
            hi = z
            g_hi = g
            if side == 1:
                g_lo *= 0.5  # Illinois: keep regula falsi from stalling on one end
            side = 1
        else:
            lo = z
            g_lo = g
            if side == -1:
                g_hi *= 0.5
            side = -1
        if hi - lo < z_tol:
            return z, True, g, True, not frozen
        dg = c_in - call.work[2][R_DFZ]  # res
        z_new = z - g / dg if dg > 0.0 else lo - 1.0
        if not (lo < z_new < hi) or abs(g) > 0.5 * abs(g_prev):
            # Newton left the bracket or stalled at a kink: regula falsi on the bracket once
            # both its ends are known, before that the secant through the last two iterates
            if np.isfinite(g_lo):
                z_new = lo - g_lo * (hi - lo) / (g_hi - g_lo)
            elif g != g_prev and np.isfinite(g_prev):
                z_new = z - g * (z - z_prev) / (g - g_prev)
            if not (lo < z_new < hi):
                z_new = 0.5 * (lo + hi)
        if np.isfinite(g_lo) and hi - lo > 0.5 * width_2ago:
            z_new = 0.5 * (lo + hi)  # bracket not halving in two steps (a jump in G): bisect
        width_2ago = width_1ago
        width_1ago = hi - lo
        z_prev = z
        g_prev = g
        if abs(z_new - z) < z_tol:
            return z_new, True, g, False, not frozen
        z = z_new
    return z, False, g, False, not frozen


@njit(cache=True)
def _lap(diag: np.ndarray, slot: int, tick: int) -> int:
    """Add the ticks since ``tick`` to diag[slot]; return the counter now."""
    now = cycles()
    diag[slot] += now - tick
    return now


@njit(cache=True)
def _volume(h0: np.ndarray, sp: np.ndarray, hl: np.ndarray, dA: float) -> float:
    total = 0.0
    for c in range(h0.shape[0]):
        for j in range(h0.shape[1]):
            total += h0[c, j] - sp[c, j] + hl[c, j]
    return total * dA


@njit(cache=True)
def _work_space(nx: int, ny: int, nyw: int, ncw_max: int):
    """A run's work space, allocated once (:mod:`.state`): the window's columns (wheel surface
    and tip circle at infinity, no ground), its patches, the nodes' marks and the flow fields'
    scratch with erosion's work list (a power of two at least nx ny long)."""
    cols = Columns(
        np.zeros(ncw_max),
        np.full(ncw_max, np.inf),
        np.full(ncw_max, np.inf),
        np.full(ncw_max, -np.inf),  # ground top per column under the wheel (build_patches)
        np.zeros(ncw_max),
        np.zeros(ncw_max),
        np.zeros(ncw_max),
        np.zeros(nyw + 1),
    )
    max_patch = ncw_max * nyw
    patches = Patches(
        np.zeros(max_patch, np.int64),
        np.zeros(max_patch, np.int64),
        np.zeros(max_patch, np.int64),
        np.zeros((max_patch, 5)),
        np.zeros(max_patch, np.int64),
        np.zeros(max_patch),
    )
    marks = Marks(np.zeros((ncw_max + 2, ny), np.int8), np.zeros((ncw_max + 2, ny)))
    scratch = FlowScratch(
        np.zeros((8, max(ncw_max, ny))),
        np.zeros((5, max(ncw_max, ny)), np.int64),
        np.zeros((1 << int(math.ceil(math.log2(nx * ny))), 2), np.int64),
        np.zeros((nx, ny), np.int8),
    )
    return cols, patches, marks, scratch


@njit(cache=True, nogil=True)
def _heap_load(prm, ground, c_ax, jw0, nyw, zw, diag):
    """The bow wave's load on the wheel this step: (surcharge [Pa] on the contact's front, its
    wedge's horizontal force [N], that force's height [m], a third up the heap), from the loose
    soil within a wheel radius ahead of the rim (the axle's column ``c_ax`` to two radii on)."""
    r_out = prm[P_R] + prm[P_HG]
    n_ahead = int(math.ceil(2.0 * r_out / prm[P_DX])) + 1
    h_b, base = bow_wave(ground, c_ax, n_ahead, jw0, nyw, zw + r_out)
    surcharge, f_b = heap_passive_pressure(prm[P_GAMMA], prm[P_TANPHI], prm[P_TANREPOSE], h_b)
    force = f_b * prm[P_B]
    diag[D_HEAP_H] = h_b
    diag[D_HEAP_F] = force
    return surcharge, force, base + h_b / 3.0


@njit(cache=True, nogil=True)  # batches run it on several threads (swt.simulate_packed)
def run_swt(prm: np.ndarray):
    """Simulate one SWT. Returns (series (n_out, N_SERIES), n_out, status, surface, diag).

    Series columns: time [s], drawbar pull F [N], driving torque T [N m], sinkage z [m] (axle drop
    from first contact with the undisturbed surface, less P_ZDATUM), normal force [N], b_eff [m],
    lateral force Fy [N] (along the axle; a steered wheel slides across the grid's rows), then
    the force budget (S_F_NORMAL .. S_FY_SIDE: F's and Fy's parts by mechanism; S_P_COMPACTION:
    the plastic work rate on the nodes [W]);
    each sample is the mean over the steps since the previous one. A run that stops early
    (status != 0) returns the samples written so far. surface (nx, ny): the final unloaded soil
    surface h0 - sp + hl [m] (ground plus loose deposits).
    """
    nx, ny, nyw, n_margin, dy, x0 = grid_shape(prm)
    dx = prm[P_DX]
    dt = prm[P_DT]
    R = prm[P_R]
    hg = prm[P_HG]
    r_out = R + hg
    ng = int(prm[P_NGROUSERS])
    tg = prm[P_TG]
    v, v_lat = prm[P_V], prm[P_VLAT]
    omega = prm[P_OMEGA]
    n_steps = int(round(prm[P_DURATION] / dt))
    out_every = int(prm[P_OUTEVERY])
    n_out_max = n_steps // out_every
    acc = np.zeros(N_SERIES)
    series = np.zeros((n_out_max, N_SERIES))
    diag = np.zeros(N_DIAG)
    diag[D_DY] = dy
    diag[D_X0] = x0
    j_start = first_row(prm, n_margin, dy)
    diag[D_JW0] = j_start
    diag[D_NYW] = nyw
    h0 = np.zeros((nx, ny))
    sp = np.zeros((nx, ny))
    sy = np.zeros((nx, ny))
    ke = np.full((nx, ny), prm[P_K])
    js = np.zeros((nx, ny))
    hl = np.zeros((nx, ny))  # loose soil deposited on top of the ground [m]
    dA = dx * dy
    diag[D_VOLUME0] = 0.0
    # largest possible footprint: k* must be positive there or the soil carries nothing
    beff_max = 2.0 * r_out * prm[P_B] / (2.0 * r_out + prm[P_B])
    if prm[P_KC] / beff_max + prm[P_KPHI] <= 0.0:
        return series[:0], 0, STATUS_NONPOSITIVE_STIFFNESS, h0 - sp + hl, diag
    ncw_max = int(math.ceil(2.0 * r_out / dx)) + 4
    cols, patches, marks, scratch = _work_space(nx, ny, nyw, ncw_max)
    xi, e, eb, fx, fz = cols.xi, cols.e, cols.eb, cols.fx, cols.fz
    res = np.zeros(N_RES)
    cflag = marks.cflag
    fwork, queue, inq = scratch.work, scratch.queue, scratch.inq
    escratch = erosion_scratch()
    vis = np.empty((2, max(ng, 1)))  # wheel_envelope's visible grousers
    work = (patches, cols, res)
    ground = Ground(h0, sp, sy, ke, js, hl)
    bulldoze = prm[P_BULLDOZE] > 0.5
    heap_weight = bulldoze and prm[P_GAMMA] > 0.0  # the bow wave weighs on the wheel's front
    tail = np.int64(0)  # erosion's work list: nodes that received soil since it last ran
    erode_every = int(prm[P_EROSIONEVERY])
    tan_repose = prm[P_TANREPOSE]
    zw = r_out  # wheel resting on the undisturbed surface (level 0), a grouser straight down
    vz = 0.0
    status = STATUS_OK
    n_out = 0
    t_steady = min(prm[P_OFF_F], prm[P_OFF_T], prm[P_OFF_Z])  # the first averaged sample [s]
    off_ft = max(prm[P_OFF_F], prm[P_OFF_T])
    n_checks = len(SETTLE_CHECKS) if prm[P_SETTLE] > 0.0 else 0
    check = 0  # the next early-stop check
    for step in range(n_steps):
        tick = cycles()
        t = (step + 1) * dt
        xw = v * t
        jw0 = rows_under(j_start, v_lat * t, dy, ny - nyw)
        theta = omega * t
        c0 = int(math.floor((xw - r_out - x0) / dx))
        c1 = int(math.ceil((xw + r_out - x0) / dx))
        c0 = max(c0, 0)
        c1 = min(c1, nx - 1)
        ncw = c1 - c0 + 1
        for k in range(ncw):
            xi[k] = x0 + (c0 + k) * dx - xw
        wheel_envelope(xi[:ncw], dx, R, ng, hg, tg, theta, e, fx, fz, vis)
        tip_circle(xi[:ncw], r_out, eb)  # the Bekker footprint's envelope
        z_low = zw + dt * vz - prm[P_W] * dt * dt / prm[P_MASS]  # free fall: lowest possible
        npatch, ztop = build_patches(ground, cols, patches, c0, ncw, jw0, nyw, z_low)
        diag[D_PATCH_STEPS] += npatch
        tick = _lap(diag, np.int64(D_CYC_GEOMETRY), tick)
        surcharge, heap_force, heap_z = 0.0, 0.0, 0.0
        if heap_weight:
            c_ax = int(round((xw - x0) / dx))
            surcharge, heap_force, heap_z = _heap_load(prm, ground, c_ax, jw0, nyw, zw, diag)
        z_new, ok = _solve_vertical(zw, vz, prm, npatch, ztop, dx, dy, nyw, work, diag, surcharge)
        if heap_force > 0.0:  # the heap's own wedge pushes the rim back above its base
            res[R_FX] -= heap_force
            res[R_T] += (heap_z - z_new) * heap_force  # eq. (10), the moment about the axle
        side = 0.0
        if v_lat != 0.0:  # a steered wheel's leading side pushes the soil beside it
            side = side_force(prm, ground, cols, c0, ncw, jw0, nyw, z_new, dx, t)
            res[R_FY] += side
        tick = _lap(diag, np.int64(D_CYC_SOLVE), tick)
        if not ok or not np.isfinite(z_new) or not np.isfinite(res[R_FX]):
            status = STATUS_UNSTABLE
            break
        if t >= t_steady and res[R_NCONTACT] > 0 and res[R_KSTAR] <= 0.0:
            # the soil does not bear the wheel's own footprint in the averaging windows
            status = STATUS_NONPOSITIVE_STIFFNESS
            break
        vz = (z_new - zw) / dt
        zw = z_new
        diag[D_NODE_STEPS] += res[R_NCONTACT]
        window = Window(c0, ncw, jw0, nyw)
        flow, plastic = commit_contact(zw, vz, prm, npatch, patches, cols, ground, marks, window)
        tick = _lap(diag, np.int64(D_CYC_COMMIT), tick)
        if bulldoze:
            compacted, spilled, tail = flow_and_deposit(
                prm, zw, vz, cols, ground, marks, window, dy, scratch, tail
            )
            diag[D_COMPACTED] += compacted
            diag[D_SPILLED] += spilled
            tick = _lap(diag, np.int64(D_CYC_FLOW), tick)
            if (step + 1) % erode_every == 0 or step == n_steps - 1:
                grid = (c0, ncw, jw0, nyw, fwork[0], h0, sp, hl, cflag, queue, inq)
                diag[D_EROSION_VISITS] += erode(grid, dx, dy, tan_repose, tail, escratch)
                tail = np.int64(0)
            tick = _lap(diag, np.int64(D_CYC_EROSION), tick)
        else:
            diag[D_COMPACTED] += flow * dA  # without flow the displaced soil is compacted
        for k in range(ncw):  # clear the marks of the nodes under the wheel
            for j in range(jw0, jw0 + nyw):
                cflag[k + 1, j] = 0
        diag[D_STEPS] += 1
        # each output sample is the mean over the steps since the last one (a box-car
        # anti-aliasing filter: grouser impacts between samples are not lost)
        # the compaction's energy per second [W]: the plastic work per area over the node area
        record_step(acc, res, r_out - zw - prm[P_ZDATUM], heap_force, side, plastic * dA / dt)
        if (step + 1) % out_every == 0 and n_out < n_out_max:
            series[n_out, S_T] = t
            for col in range(S_F, N_SERIES):
                series[n_out, col] = acc[col] / out_every
                acc[col] = 0.0
            n_out += 1
            if check < n_checks and t >= off_ft + SETTLE_CHECKS[check] * (n_steps * dt - off_ft):
                check += 1
                if settled(series[:n_out], prm, n_steps * dt):
                    break
        if r_out - zw > prm[P_MAXSINK]:
            status = STATUS_BOTTOMED_OUT
            break
    diag[D_VOLUME1] = _volume(h0, sp, hl, dA)
    return series[:n_out], n_out, status, h0 - sp + hl, diag
