"""Contact, footprint and stresses at a trial axle height (paper section 3.1, eq. (7)-(10)).

Per step the DEM nodes under the wheel are grouped into *patches*: runs of consecutive nodes of one
column (same x, neighbouring y) whose soil state is identical. Straight grousers make the wheel's
surface the same across y, so identical nodes carry identical stresses and the Bekker power law of
eq. (7) is evaluated once per patch instead of once per node (a column typically holds one interior
run and two edge runs). Node state: reference level h0 (the undisturbed level, raised where soil is
deposited), plastic sinkage sp, yield stress sy (largest stress carried), unloading stiffness ke
and, for the displacement form of eq. (8), the accumulated shear path js.

Elastic-plastic law per node (as in SCM / Chrono's SCMTerrain): with sinkage p = h0 - hit,
the elastic trial stress is ke (p - sp); above the yield stress sy the node is on the Bekker curve
sigma = (k_c / b_eff + k_phi) p^n and yields. Soil cannot pull: sigma >= 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import (
    P_C,
    P_DSOIL,
    P_DT,
    P_INCL,
    P_J,
    P_KC,
    P_KPHI,
    P_N,
    P_OMEGA,
    P_SHEARDISP,
    P_SHEARSCALE,
    P_SLIPV,
    P_STUCKSOIL,
    P_TANDELTA,
    P_TANPHI,
    P_TAPER,
    P_V,
    P_VLAT,
)
from .state import Columns, Ground, Patches

# Nodes whose levels (reference, unloaded surface, elastic range, shear path) differ by less than
# this [m] share one stress evaluation; each node's own state is still updated exactly. 0.1 um is a
# stress difference of at most K * 1e-7 (5 Pa at the default K). Erosion works node by node and
# leaves tiny differences across y that would otherwise split every column into single nodes.
SAME_TOL = 1e-7

# indices of the `res` vector filled by evaluate_contact
R_FX = 0  # drawbar pull: horizontal soil force on the wheel, + forward [N]
R_FZ = 1  # vertical soil force on the wheel, + up [N]
R_T = 2  # driving torque the motor supplies [N m]
R_DFZ = 3  # d(Fz)/d(axle height) [N/m]
R_NCONTACT = 4  # loaded nodes
R_BEFF = 5  # effective contact width b_eff = 2 A / L [m]
R_KSTAR = 6  # k* = k_c / b_eff + k_phi of the footprint [N/m^(n+2)]
R_NORM = 7  # normalisation of the border taper
R_CMIN = 8  # footprint extent: first and last loaded column of the window
R_CMAX = 9
R_FY = 10  # lateral force: soil force on the wheel along its axle (+y) [N]
# the drawbar pull's parts (R_FX = R_FXN + R_FXS + R_FXCAP): what the normal stresses give (eq.
# (9)'s sigma n_x: compaction and bulldozing resistance, the heap's surcharge on the face), what
# the shear gives (-tau t_x: thrust or drag), and the Coulomb cap's cut of the forward thrust
R_FXN = 11
R_FXS = 12
R_FXCAP = 13
N_RES = 14


@njit(cache=True)
def inclination_factor(
    nx: float, nz: float, tx: float, tz: float, mu: float, m: float, ty: float = 0.0
) -> float:
    """Bearing-capacity factor (1 - alpha / 90 deg)^m of a node's traction on the soil.

    The wheel pushes the soil along -n and drags it along t (the wheel's slip direction) with
    the mobilised friction mu = tau / sigma, so the traction on the soil points along -n + mu t,
    inclined by alpha from straight down. Bekker's pressure-sinkage law describes a plate
    pushed vertically; a footing loaded at an inclination alpha carries the factor
    (1 - alpha / 90 deg)^2 of its vertical bearing capacity (Meyerhof 1953, i_q). At the front of
    a skidding wheel alpha = theta + delta (the soil is dragged up and forwards), at the front of
    a driven wheel theta - delta: skid softens the soil ahead of the wheel, drive does not. A
    traction that does not press down (alpha >= 90 deg) finds no bearing.
    """
    dx = -nx + mu * tx
    dz = -nz + mu * tz
    # a steered wheel's slip has a component ty along the axle: the traction's horizontal part
    # is then (dx, mu ty)
    horizontal = abs(dx) if ty == 0.0 else math.hypot(dx, mu * ty)
    i = 0.0
    if dz < 0.0:
        i = (1.0 - math.atan2(horizontal, -dz) / (0.5 * math.pi)) ** m
    return 1.0 - (1.0 - i) * nz * nz


@njit(cache=True, inline="always")
def coulomb_cap(
    Fx: float, Ty: float, Fx_fwd: float, Ty_fwd: float, cap: float
) -> tuple[float, float]:
    """The drawbar pull and moment (Fx [N], Ty [N m]) within the Coulomb sliding limit of the
    soil under the wheel, ``cap`` = c A + W tan(phi) (Micklethwaite's maximum tractive effort):
    thrust beyond it (grouser faces pressing columns that Bekker's law alone does not bound)
    shears the soil instead, so the forward contributions (Fx_fwd, their moment Ty_fwd) are
    scaled to the limit, and the torque with them."""
    if Fx > cap and Fx_fwd > 0.0:
        lam = max((cap - (Fx - Fx_fwd)) / Fx_fwd, 0.0)
        Ty -= (1.0 - lam) * Ty_fwd
        Fx = cap if lam > 0.0 else Fx - Fx_fwd
    return Fx, Ty


@njit(cache=True, inline="always")
def surface_velocity(
    v: float, vz: float, omega: float, rx: float, rz: float, nx: float, nz: float
) -> tuple[float, float, float]:
    """Velocity of the wheel's surface point r = (rx, rz) from the axle over the ground [m/s]:
    the axle's (v, vz) plus omega x r (the wheel turning at omega [rad/s], clockwise for
    forward travel), and its component along the surface normal (nx, nz). Returns (v_x, v_z,
    v_n); the slip velocity along the surface is (v_x, v_z) - v_n (nx, nz)."""
    vpx = v + omega * rz
    vpz = vz - omega * rx
    return vpx, vpz, vpx * nx + vpz * nz


@njit(cache=True, inline="always")
def slip_direction(vx: float, vy: float, vz: float) -> tuple[float, float, float, float]:
    """(|v|, and the unit vector along v) of a slip velocity v [m/s]; a zero vector for none."""
    vt = math.sqrt(vx * vx + vz * vz + vy * vy)
    if vt > 0.0:
        return vt, vx / vt, vy / vt, vz / vt
    return vt, 0.0, 0.0, 0.0


@njit(cache=True)
def build_patches(
    ground: Ground,
    cols: Columns,
    patches: Patches,
    c0: int,
    ncw: int,
    jw0: int,
    nyw: int,
    z_low: float,
) -> tuple[int, float]:
    """Group the nodes under the wheel into patches of identical state.

    Only columns that the wheel can touch with its axle at or above ``z_low`` (the free-fall
    height of this step, a lower bound of the solution) are kept. Returns (number of patches,
    highest axle height at which any node touches the wheel); pst[p] = (h0, sp, sy, ke, js).
    gtop[k]: highest ground level h0 - sp of column k under the wheel's width [m] (-inf beyond the
    tip circle ``eb``), from which evaluate_contact finds the tip circle's footprint.
    """
    h0, sp, sy, ke, js = ground.h0, ground.sp, ground.sy, ground.ke, ground.js
    e, eb, gtop = cols.e, cols.eb, cols.gtop
    pc, pj0, pj1, pst = patches.pc, patches.pj0, patches.pj1, patches.pst
    npatch = 0
    ztop = -np.inf
    gtop[ncw:] = -np.inf
    for k in range(ncw):
        gtop[k] = -np.inf
        if not np.isfinite(min(e[k], eb[k])):
            continue
        c = c0 + k
        top = -np.inf
        for j in range(jw0, jw0 + nyw):
            top = max(top, h0[c, j] - sp[c, j])
        gtop[k] = top
        if not np.isfinite(e[k]) or z_low + e[k] >= top:
            continue  # the wheel stays above every node of this column
        j = 0
        while j < nyw:
            a = h0[c, jw0 + j]
            b = sp[c, jw0 + j]
            s = sy[c, jw0 + j]
            q = ke[c, jw0 + j]
            w = js[c, jw0 + j]
            j1 = j + 1
            while j1 < nyw:
                jj = jw0 + j1
                # compare levels [m]: reference, unloaded surface, elastic range sy/ke
                if (
                    abs(h0[c, jj] - a) > SAME_TOL
                    or abs(sp[c, jj] - b) > SAME_TOL
                    or abs(sy[c, jj] / ke[c, jj] - s / q) > SAME_TOL
                    or abs(js[c, jj] - w) > SAME_TOL
                ):
                    break
                j1 += 1
            pc[npatch] = k
            pj0[npatch] = j
            pj1[npatch] = j1
            pst[npatch, 0] = a
            pst[npatch, 1] = b
            pst[npatch, 2] = s
            pst[npatch, 3] = q
            pst[npatch, 4] = w
            top = a - b - e[k]
            if top > ztop:
                ztop = top
            npatch += 1
            j = j1
    return npatch, ztop


@njit(cache=True)
def tip_footprint_length(
    zw: float, xi: np.ndarray, eb: np.ndarray, gtop: np.ndarray, dx: float
) -> float:
    """Length along x of the tip circle's footprint with the axle at height zw [m].

    The penetration d_k = gtop[k] - (zw + eb[k]) of the circle through the grouser tips into each
    column's ground is interpolated linearly between column centres, so the front and rear edges
    (its zero crossings) and the length move continuously with zw and the soil state. One column
    (dx) at least: evaluate_contact asks only when the wheel touches, and a grouser's corner (just
    outside the circle) can touch before the circle does. Columns outside this step's window have
    gtop = -inf (build_patches).
    """
    ncw = gtop.shape[0]
    kf = -1
    kr = -1
    for k in range(ncw):
        if gtop[k] - (zw + eb[k]) > 0.0:
            if kr < 0:
                kr = k
            kf = k
    if kf < 0:
        return dx
    d = gtop[kf] - (zw + eb[kf])
    x_front = xi[kf] + 0.5 * dx
    if kf + 1 < ncw and np.isfinite(gtop[kf + 1]) and np.isfinite(eb[kf + 1]):
        x_front = xi[kf] + dx * d / (d - (gtop[kf + 1] - (zw + eb[kf + 1])))
    d = gtop[kr] - (zw + eb[kr])
    x_rear = xi[kr] - 0.5 * dx
    if kr > 0 and np.isfinite(gtop[kr - 1]) and np.isfinite(eb[kr - 1]):
        x_rear = xi[kr] - dx * d / (d - (gtop[kr - 1] - (zw + eb[kr - 1])))
    return max(x_front - x_rear, dx)


@njit(cache=True, inline="always")
def _footprint(
    zw: float,
    prm: np.ndarray,
    npatch: int,
    patches: Patches,
    cols: Columns,
    dx: float,
    dy: float,
    nyw: int,
    res: np.ndarray,
    freeze: bool,
) -> tuple[int, float, float, int, int]:
    """evaluate_contact's first pass: which patches touch (``pflag`` 1, ``psig`` 0 where free),
    the loaded node count, k* of the tip circle's footprint, the border taper's normalisation
    (``gx``, ``gyc`` filled) and the loaded columns' range; frozen from ``res`` with
    ``freeze``. Returns (loaded nodes, k*, taper normalisation, first and last loaded column)."""
    pc, pj0, pj1, pst, pflag, psig = patches
    e, gx, gyc = cols.e, cols.gx, cols.gyc
    # ---- pass 1: which patches touch, footprint extent
    ncont = 0
    cmin = 1 << 30
    cmax = -1
    jmin = 1 << 30
    jmax = -1
    for p in range(npatch):
        k = pc[p]
        if zw + e[k] < pst[p, 0] - pst[p, 1]:
            pflag[p] = 1
            ncont += pj1[p] - pj0[p]
            cmin = min(cmin, k)
            cmax = max(cmax, k)
            jmin = min(jmin, pj0[p])
            jmax = max(jmax, pj1[p] - 1)
        else:
            pflag[p] = 0
            psig[p] = 0.0
    if ncont == 0:
        res[R_NCONTACT] = 0.0
        return 0, 0.0, 1.0, cmin, cmax
    taper = prm[P_TAPER] > 0.5
    if freeze and res[R_NCONTACT] > 0:
        kstar = res[R_KSTAR]
        norm = res[R_NORM]
        cmin = int(res[R_CMIN])
        cmax = int(res[R_CMAX])
    else:
        # Bekker's plate: the tip circle's footprint, length l by the wheel's width w
        length = tip_footprint_length(zw, cols.xi, cols.eb, cols.gtop, dx)
        width = nyw * dy
        beff = length * width / (length + width)  # 2A/L of the l x w rectangle
        kstar = prm[P_KC] / beff + prm[P_KPHI]
        res[R_NCONTACT] = ncont
        res[R_BEFF] = beff
        res[R_KSTAR] = kstar
        res[R_CMIN] = cmin
        res[R_CMAX] = cmax
        # ---- border taper (separable), normalised over the loaded nodes
        norm = 1.0
        if taper:
            nxe = cmax - cmin + 1
            nye = jmax - jmin + 1
            for k in range(cmin, cmax + 1):
                gx[k] = math.sin(math.pi * (k - cmin + 0.5) / nxe)
            gyc[0] = 0.0
            for j in range(nyw):
                g = 0.0
                if jmin <= j <= jmax:
                    g = math.sin(math.pi * (j - jmin + 0.5) / nye)
                gyc[j + 1] = gyc[j] + g
            ssum = 0.0
            for p in range(npatch):
                if pflag[p] > 0:
                    ssum += gx[pc[p]] * (gyc[pj1[p]] - gyc[pj0[p]])
            norm = ncont / ssum
        res[R_NORM] = norm
    return ncont, kstar, norm, cmin, cmax


@njit(cache=True, inline="always")
def evaluate_contact(
    zw: float,
    vz: float,
    prm: np.ndarray,
    npatch: int,
    patches: Patches,
    cols: Columns,
    dx: float,
    dy: float,
    nyw: int,
    res: np.ndarray,
    freeze: bool,
    surcharge: float,
) -> None:
    """Stresses and resultant soil forces for the axle at height zw moving down at -vz.

    Fills ``res`` (see R_* indices), ``pflag`` (0 free, 1 elastic contact, 2 yielding) and ``psig``
    (untapered stress of eq. (7) per patch, Pa). Bekker's plate width is b_eff = l w / (l + w) of
    the *tip circle's footprint*, w the wheel's width and l the length over which ``eb``, the
    circle through the grouser tips (the rim for a smooth wheel), is below the ground ``gtop``:
    the trapped soil moves with the wheel (Wong & Reece's effective radius r + h_g), so a
    grousered wheel presses on the soil as one plate, not as grouser tips one cell wide; l is
    interpolated between columns, so k* = k_c / b_eff + k_phi is continuous in the axle height.
    The border taper gamma_i (separable half sines over the loaded nodes' bounding box, mean one
    over them) is evaluated on the loaded footprint. eq. (9)-(10) with the cell area dA = dx dy.
    ``surcharge`` [Pa]: the bow wave's passive pressure (deformation.heap_passive_pressure), a
    horizontal stress on the front (normal stress surcharge nx^2 where nx < 0), outside Bekker's
    law (it moves no node's yield).

    With ``freeze`` the footprint quantities (k*, taper extent and normalisation) of the previous
    call are kept: G(z) is then smooth apart from contact kinks, which lets the vertical solve
    converge in few steps; the solve ends with an unfrozen evaluation at the solution.
    """
    pc, pj0, pj1, pst, pflag, psig = patches
    xi, e, fx, fz, gx, gyc = cols.xi, cols.e, cols.fx, cols.fz, cols.gx, cols.gyc
    res[R_FX] = res[R_FZ] = res[R_T] = res[R_DFZ] = res[R_FY] = 0.0
    res[R_FXN] = res[R_FXS] = res[R_FXCAP] = 0.0
    n_exp = prm[P_N]
    tanphi = prm[P_TANPHI]  # the soil's strength under the wheel (the Coulomb cap)
    tandelta = prm[P_TANDELTA]  # the soil on the wheel's surface (eq. (8)), at phi where it
    stuck_soil = prm[P_STUCKSOIL] > 0.5 and tandelta < tanphi  # sticks (stuck_shear 'soil')
    coh = prm[P_C]
    dsoil = prm[P_DSOIL]
    J = prm[P_J]
    dt = prm[P_DT]
    v = prm[P_V]
    # the surface that shears the soil turns at omega and lies kin times farther out than the
    # contact circle (rim bearing: the grouser tips), so it moves as omega * kin at the circle;
    # its slip over the ground sees the axle's velocity sv times (layout._slip_velocity_scale)
    kin = prm[P_SHEARSCALE]
    omega = prm[P_OMEGA] * kin
    sv = prm[P_SLIPV]
    # a steered wheel slides along its axle at the axle's lateral velocity (the surface turns
    # in the wheel's plane): the slip velocity, the shear's direction t and eq. (8)'s
    # mobilisation are those of the vector (vtx, vty, vtz) (Janosi-Hanamoto along the slip
    # direction: Ishigami et al. 2007; Chrono's SCM)
    vty = prm[P_VLAT] * sv
    disp_form = prm[P_SHEARDISP] > 0.5
    incl_exp = prm[P_INCL]
    ncont, kstar, norm, cmin, cmax = _footprint(
        zw, prm, npatch, patches, cols, dx, dy, nyw, res, freeze
    )
    if ncont == 0:
        return
    dA = dx * dy
    taper = prm[P_TAPER] > 0.5
    # ---- pass 2: stresses and forces (patches come column by column)
    Fx = 0.0
    Fxn = 0.0  # the normal stresses' part of Fx
    Fy = 0.0
    Fz = 0.0
    Ty = 0.0
    dFz = 0.0
    Fx_fwd = 0.0  # forward (thrust) contributions and their moment
    Ty_fwd = 0.0
    k_prev = -1
    rx = rz = nx = nz = tx = ty = tz = sd = dsd = fsh = vt = mu = 0.0
    for p in range(npatch):
        if pflag[p] == 0:
            continue
        k = pc[p]
        if k != k_prev:
            # contact kinematics of this column: point r = (xi, e) from the axle,
            # velocity v_axle + omega x r; normal n (soil force direction), slip direction t
            k_prev = k
            rx = xi[k]
            rz = e[k]
            nx = fx[k]
            nz = fz[k]
            vpx, vpz, vn = surface_velocity(v * sv, vz * sv, omega, rx, rz, nx, nz)
            pen = -vn / sv  # rate of penetration into the soil [m/s]
            sd, dsd = (dsoil * pen, -dsoil * nz / dt) if dsoil > 0.0 and pen > 0.0 else (0.0, 0.0)
            vt, tx, ty, tz = slip_direction(vpx - vn * nx, vty, vpz - vn * nz)
            fsh = 1.0 - math.exp(-vt / J)
            # the surface pushes into the soil more than it slides: the soil moves with it
            mu = tanphi if stuck_soil and pen > 0.0 and vt <= tandelta * pen * sv else tandelta
        if disp_form:
            fsh = 1.0 - math.exp(-(pst[p, 4] + vt * dt) / J)
        rows = pj1[p] - pj0[p]
        sink = pst[p, 0] - (zw + e[k])
        sel = pst[p, 3] * (sink - pst[p, 1])
        if sel > pst[p, 2]:
            pflag[p] = 2
            if kstar > 0.0:
                # the inclination factor scales the yield stress only (elastic nodes skip it)
                incl = 1.0
                if incl_exp > 0.0:
                    incl = inclination_factor(nx, nz, tx, tz, fsh * mu, incl_exp, ty)
                sb = incl * kstar * sink**n_exp
                dsb = n_exp * sb / sink
            else:
                sb = 0.0
                dsb = 0.0
        else:
            sb = sel
            dsb = pst[p, 3]
        psig[p] = sb
        if taper:
            gam = norm * gx[min(max(k, cmin), cmax)] * (gyc[pj1[p]] - gyc[pj0[p]])
        else:
            gam = float(rows)
        sig_sum = gam * sb + rows * sd  # sum over the patch's rows of eq. (7) [Pa]
        if surcharge > 0.0 and nx < 0.0:
            sig_sum += rows * surcharge * nx * nx  # the heap ahead, horizontal on the face
        tau_sum = fsh * (coh * rows + mu * sig_sum)  # eq. (8)
        dfx = (sig_sum * nx - tau_sum * tx) * dA  # eq. (9): shear opposes the sliding
        dfz = (sig_sum * nz - tau_sum * tz) * dA
        Fx += dfx
        Fxn += sig_sum * nx * dA
        Fy -= tau_sum * ty * dA  # the shear opposes the sideways sliding too
        Fz += dfz
        Ty += kin * (rz * dfx - rx * dfz)  # eq. (10), moment about the axle (y component)
        if dfx > 0.0:
            Fx_fwd += dfx
            Ty_fwd += kin * rz * dfx
        dsig = -gam * dsb + rows * dsd  # d(sig_sum)/d(zw): sinkage falls as the axle rises
        dFz += (dsig * nz - fsh * mu * dsig * tz) * dA
    res[R_FXN] = Fxn
    res[R_FXS] = Fx - Fxn
    Fx, Ty = coulomb_cap(Fx, Ty, Fx_fwd, Ty_fwd, coh * ncont * dA + max(Fz, 0.0) * tanphi)
    res[R_FXCAP] = Fx - res[R_FXN] - res[R_FXS]
    res[R_FX] = Fx
    res[R_FY] = Fy
    res[R_FZ] = Fz
    res[R_T] = -Ty
    res[R_DFZ] = dFz
