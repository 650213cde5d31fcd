"""Population jumps: an independence proposal for the inner steps of a surrogate transition
(``TMCMCSettings.surrogate_jumps``).

A random walk moves a chain by about beta posterior sd per accepted step, so a stage's few
model-corrected moves leave most chains near their (resampled, repeated) starts and the next
population holds few independent lineages. An independence Metropolis-Hastings step proposes
u' ~ t_nu(m, S) in walk coordinates (:mod:`scm_core.inference.walk_space`), a multivariate
Student t with the weighted mean m and covariance S of the stage's population (nu =
:data:`JUMP_DOF`: heavier tails than the target's bulk, so that the weight pi / q stays
bounded where it matters), and accepts with min(1, pi~(x') q(x) / (pi~(x) q(x'))) (Tierney
1994). On the surrogate target pi~ it costs no model run, and one accepted jump forgets the
chain's start. The step is pi~-reversible, and so is its mixture with the random walk (each
inner step a jump with the fixed probability ``surrogate_jumps``), so the surrogate transition
stays exact for pi (:mod:`scm_core.inference.surrogate`).

The proposal density in x gains the Jacobian of the log columns, as the walk's:
log q(x) - log q(x') = log t(u) - log t(u') + sum_j (u'_j - u_j) over the log columns.
Every function works row by row (results independent of the number of rows).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from scm_core.inference import portable
from scm_core.inference.walk_space import rows_times

__all__ = ["JUMP_DOF", "jump_log_density", "jump_proposal"]

#: degrees of freedom of the jump proposal's Student t
JUMP_DOF = 5.0


def jump_proposal(
    mean: NDArray[np.float64],
    chol: NDArray[np.float64],
    Z: NDArray[np.float64],
    chi2: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Draws u = mean + chol z / sqrt(g / nu) (m, d) of the t proposal from standard normals Z
    (m, d) and chi-square(nu) variates ``chi2`` (m,)."""
    scale = 1.0 / np.sqrt(chi2 / JUMP_DOF)
    return mean + rows_times(chol, Z) * scale[:, None]


def jump_log_density(
    U: NDArray[np.float64], mean: NDArray[np.float64], chol_inv: NDArray[np.float64]
) -> NDArray[np.float64]:
    """log t_nu(u; mean, chol chol^T) (m,) up to its constant (which cancels in the
    Metropolis-Hastings ratio): -(nu + d) / 2 log(1 + |chol^-1 (u - mean)|^2 / nu)."""
    W = rows_times(chol_inv, U - mean)
    q = np.zeros(U.shape[0])
    for j in range(W.shape[1]):
        q = q + W[:, j] * W[:, j]
    return -0.5 * (JUMP_DOF + U.shape[1]) * portable.log1p(q / JUMP_DOF)
