"""The discrete Lagrangian L_d(g_k, f_k) straight from its integral definition (test helper),
plus the rotations, scenes and random states the physics tests share.

L_d uses neither esp_gym.verify.reference nor esp_gym.kernels: the string part is the paper's integral
form of ``L_{d_{k,a}}`` evaluated by Gauss-Legendre quadrature over the natural coordinate
zeta in [0, 1] (not the closed form (Ldka)), with erratum 1 (kinetic prefactor h/2, not 1/h)
applied; the closed form's erratum 2 (missing kappa) cannot arise here, since the elastic term
is integrated from EA directly. The rigid-body part is (Ldkrb) as printed.

    L_{d_{k,a}} = h/2 int_0^1 mu |v_{k,a}(zeta)|^2 u dzeta
                  - h/2 int_0^1 [W(|r'_{k,a}|) - mu g r_{k,a}(zeta).e3] u dzeta
                  - h/2 int_0^1 [W(|r'_{k+1,a}|) - mu g r_{k+1,a}(zeta).e3] u dzeta
    r_{k,a}(zeta) = (1 - zeta) r_{k,a} + zeta r_{k,a+1},    r'_{k,a} = (r_{k,a+1} - r_{k,a})/u,
    v_{k,a}(zeta) = ((1 - zeta) dr_{k,a} + zeta dr_{k,a+1})/h

with the strain energy density W(s) = 1/2 EA (s - 1)^2 of the paper's law (``string.law:
elastic``) or W(s) = 1/2 EA max(s - 1, 0)^2 of the tension-only law (``slack``; C^1, so first
derivatives of L_d exist everywhere, second ones jump where |r'| = 1). A free pivot (``pivot.kind:
free``, docs/physics.md "Inputs") adds its point mass M_p at row 0, with the same midpoint
kinetic and trapezoidal gravity terms as the body's translation in (Ldkrb)::

    L_{d_{k,p}} = M_p/(2h) |dr_0|^2 + h/2 M_p g (r_0 + (r_0 + dr_0)).e3

Arrays: r, dr (N+1, 3) [m] with row 0 the pivot (fixed: dr[0] = 0 and L_{d_{k,p}} = 0; free:
row 0 is a free node like the others), R (3, 3) body -> spatial.
The rotation increment F_k is passed as ``FmI = F_k - I``: F_k = I + O(h), and a central
difference of L_d in F would otherwise difference values of ``I - F`` that each carry an
absolute error eps (docs/physics.md, "Round-off"). L_d is in [J s].
"""
import numpy as np

E3 = np.array([0.0, 0.0, 1.0])

#: Gauss-Legendre nodes/weights on [0, 1]. The integrands are polynomials in zeta of degree
#: <= 2 (kinetic), 1 (gravity) and 0 (elastic), so 3 points are exact; 4 leave a margin.
_XI, _W = np.polynomial.legendre.leggauss(4)
ZETA = 0.5 * (_XI + 1.0)
WEIGHTS = 0.5 * _W


def string_kinetic(scene, dr) -> float:
    """h/2 sum_a int_0^1 mu |v_{k,a}(zeta)|^2 u dzeta [J s] (erratum 1: h/2, not 1/h). With
    ``mass_model: lumped`` the zeta-integral is taken by the trapezoid rule (nodal quadrature),
    which is what lumping the mass means: m/2 |v|^2 at each end of an element."""
    h, mu, u = scene.h, scene.string.mass_per_length, scene.string.u
    if scene.string.mass_model == "lumped":
        v2 = np.sum((dr / h) ** 2, axis=1)
        return 0.5 * h * float(np.sum(0.5 * mu * u * (v2[:-1] + v2[1:])))
    v = ((1.0 - ZETA)[None, :, None] * dr[:-1, None, :] + ZETA[None, :, None] * dr[1:, None, :]) / h
    return 0.5 * h * float(np.sum(WEIGHTS[None, :] * mu * np.sum(v * v, axis=2) * u))


def string_potential(scene, r) -> float:
    """sum_a int_0^1 [W(|r'_a|) - mu g r_a(zeta).e3] u dzeta [J] at one time; W(s) = 1/2 EA (s - 1)^2,
    or 1/2 EA max(s - 1, 0)^2 for the slack law (a compressed element stores no energy)."""
    mu, u, EA, g = scene.string.mass_per_length, scene.string.u, scene.string.EA, scene.gravity
    strain = np.sqrt(np.sum(((r[1:] - r[:-1]) / u) ** 2, axis=1)) - 1.0  # (N,), constant in zeta
    if scene.string.law == "slack":
        strain = np.maximum(strain, 0.0)
    z = (1.0 - ZETA)[None, :] * r[:-1, None, 2] + ZETA[None, :] * r[1:, None, 2]  # r_a(zeta).e3
    integrand = 0.5 * EA * strain[:, None] ** 2 - mu * g * z
    return float(np.sum(WEIGHTS[None, :] * integrand * u))


def string_elastic_mean_length(scene, r0, r1) -> float:
    """The implicit string's elastic term: sum_a int_0^1 W(sbar_a) u dzeta [J] with the element's
    stretch sbar_a = (|r'_{k,a}| + |r'_{k+1,a}|)/2, the mean of its stretches at both ends of the
    step (``solver.string: implicit``, docs/physics.md). The kernel's on steps where no element
    switches between slack and taut; one that does takes the energy's secant instead (docs/physics.md,
    "The slack switch"; tests/test_implicit.py)."""
    u, EA = scene.string.u, scene.string.EA
    s0 = np.sqrt(np.sum(((r0[1:] - r0[:-1]) / u) ** 2, axis=1))
    s1 = np.sqrt(np.sum(((r1[1:] - r1[:-1]) / u) ** 2, axis=1))
    strain = 0.5 * (s0 + s1) - 1.0
    if scene.string.law == "slack":
        strain = np.maximum(strain, 0.0)
    return float(np.sum(0.5 * EA * strain ** 2 * u))  # W is constant along the element


def discrete_gradient_forces(scene, r0, r1, l0=None, l1=None) -> np.ndarray:
    """The implicit string's elastic forces over a step in its energy-momentum form (``solver.
    implicit_form: energy_momentum``, docs/physics.md) [N], (N+1, 3): element a pulls node a by
    T_a d_a and node a+1 by -T_a d_a, with d_a = (x_k + x_{k+1})/(|x_k| + |x_{k+1}|) and T_a the
    elastic energy's secant in the element's stretch s = |x| - u, (V(s_{k+1}) - V(s_k))/(s_{k+1} -
    s_k), V(s) = kappa/2 s^2 (max(s, 0)^2 for the slack law). The rest length u is l/N at each end
    (l0, l1: a winch's unstretched lengths; the scene's by default) and kappa = EA over its mean."""
    n, EA = scene.string.elements, scene.string.EA
    u0 = (scene.string.length if l0 is None else l0) / n
    u1 = (scene.string.length if l1 is None else l1) / n
    kappa = EA / (0.5 * (u0 + u1))
    x0, x1 = np.diff(r0, axis=0), np.diff(r1, axis=0)
    len0, len1 = np.linalg.norm(x0, axis=1), np.linalg.norm(x1, axis=1)
    s0, s1 = len0 - u0, len1 - u1
    e0, e1 = (np.maximum(s0, 0.0), np.maximum(s1, 0.0)) if scene.string.law == "slack" else (s0, s1)
    with np.errstate(invalid="ignore", divide="ignore"):
        tension = np.where(s1 != s0, 0.5 * kappa * (e1 ** 2 - e0 ** 2) / (s1 - s0), kappa * e0)
    pull = tension[:, None] * (x0 + x1) / (len0 + len1)[:, None]
    forces = np.zeros_like(r0)
    forces[:-1] += pull
    forces[1:] -= pull
    return forces


def string_lagrangian(scene, r, dr) -> float:
    """L_{d_{k,str}} = sum_a L_{d_{k,a}} [J s]: kinetic minus trapezoidal-in-time potential;
    for the implicit string (``solver.string: implicit``) the elastic part is instead
    -h V_e at the elements' mean stretches (:func:`string_elastic_mean_length`)."""
    h = scene.h
    if scene.solver.string == "implicit":
        gravity = scene.model_copy(update={"string": scene.string.model_copy(update={"EA": 0.0})})
        return (string_kinetic(scene, dr) - 0.5 * h * string_potential(gravity, r)
                - 0.5 * h * string_potential(gravity, r + dr) - h * string_elastic_mean_length(scene, r, r + dr))
    return (string_kinetic(scene, dr)
            - 0.5 * h * string_potential(scene, r) - 0.5 * h * string_potential(scene, r + dr))


def rigid_body_lagrangian(scene, r_attach, R, dr_attach, FmI) -> float:
    """(Ldkrb) as printed, with F_k = I + FmI [J s]::

        1/(2h) M |dr|^2 + 1/h tr((I - F) J_d) + M/h dr . R (F - I) rho_c
        + h/2 M g (r + R rho_c).e3 + h/2 M g (r + dr + R F rho_c).e3,   J_d = tr(J)/2 I - J
    """
    h, M, g = scene.h, scene.body.mass, scene.gravity
    J = scene.body.J
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    rho = np.array(scene.body.rho_c, dtype=float)
    return float(0.5 / h * M * dr_attach @ dr_attach
                 + np.trace(-FmI @ Jd) / h
                 + M / h * dr_attach @ (R @ (FmI @ rho))
                 + 0.5 * h * M * g * (r_attach + R @ rho) @ E3
                 + 0.5 * h * M * g * (r_attach + dr_attach + R @ rho + R @ (FmI @ rho)) @ E3)


def pivot_lagrangian(scene, r_pivot, dr_pivot) -> float:
    """L_{d_{k,p}} = M_p/(2h) |dr_0|^2 + h/2 M_p g (2 r_0 + dr_0).e3 of a free pivot [J s]; 0 when
    the pivot is fixed."""
    if not scene.pivot.is_free:
        return 0.0
    h, Mp, g = scene.h, scene.pivot.mass, scene.gravity
    return float(0.5 / h * Mp * dr_pivot @ dr_pivot + 0.5 * h * Mp * g * (2.0 * r_pivot + dr_pivot) @ E3)


def discrete_lagrangian(scene, r, R, dr, FmI) -> float:
    """L_d(g_k, f_k) = sum_a L_{d_{k,a}} + L_{d_{k,rb}} (Ldk) (+ L_{d_{k,p}} for a free pivot)
    [J s], g_k = (r, R), f_k = (dr, I + FmI)."""
    return (string_lagrangian(scene, r, dr) + rigid_body_lagrangian(scene, r[-1], R, dr[-1], FmI)
            + pivot_lagrangian(scene, r[0], dr[0]))


def winch_string_lagrangian(scene, r, dr, l0, l1, convective=True) -> float:
    """The string's L_d over a step in which a winch takes the unstretched length from l0 to l1
    [J s] (docs/physics.md, "The winch"), from the material's kinetic energy: the nodes sit at
    fixed fractions of l, so the material at element e, natural coordinate zeta, moves at

        v = ((1 - zeta) dr_e + zeta dr_{e+1}) / h + lambda (k - zeta) x_e,   lambda = l'/l, k = N - e,

    and the mass per length mu, the rest length u = l/N and EA/u follow l(t) = l0 + t (l1 - l0)/h.
    The kinetic energy's velocity-dependent part (quadratic and linear in dr) is integrated exactly
    over the step, by Gauss-Legendre in time and zeta along the straight-line motion; the part
    free of dr (|lambda (k - zeta) x_e|^2) and the potential by the trapezoid rule in time.
    ``convective=False`` drops lambda's terms (a negative control: the material does not flow).
    With ``mass_model: lumped`` every zeta-integral is the trapezoid rule (as the lumped mass is).
    With ``solver.string: implicit`` the elastic term is instead -h EA/(2 ubar) phi(sbar)^2 per
    element, sbar the mean of its stretches |x| - u at both ends (u = l/N at each) and ubar = (u_k +
    u_k+1)/2: the implicit string's mean-length energy with the rest length moving."""
    h, mu, EA, g, n = scene.h, scene.string.mass_per_length, scene.string.EA, scene.gravity, scene.string.elements
    speed = (l1 - l0) / h if convective else 0.0
    lumped = scene.string.mass_model == "lumped"
    nodes, weights = (np.array([0.0, 1.0]), np.array([0.5, 0.5])) if lumped else (ZETA, WEIGHTS)
    k = (n - np.arange(n))[:, None, None]
    z = nodes[None, :, None]
    shape = (1.0 - z) * dr[:-1, None, :] + z * dr[1:, None, :]  # (N, zeta, 3)

    def drift(l, x):  # lambda (k - zeta) x_e: the material's velocity along the nodes' frame
        return speed / l * (k - z) * x[:, None, :]

    total = 0.0
    for tau, w_tau in zip(ZETA, WEIGHTS):
        l = l0 + tau * (l1 - l0)
        x = (r + tau * dr)[1:] - (r + tau * dr)[:-1]
        v, c = shape / h, drift(l, x)
        moving = np.sum(v * v, axis=2) + 2.0 * np.sum(v * c, axis=2)
        total += h * w_tau * 0.5 * mu * (l / n) * float(np.sum(weights[None, :] * moving))
    implicit = scene.solver.string == "implicit"
    stretch = []
    for l, q in ((l0, r), (l1, r + dr)):
        x, u = q[1:] - q[:-1], l / n
        c = drift(l, x)
        t0 = 0.5 * mu * u * float(np.sum(weights[None, :] * np.sum(c * c, axis=2)))
        stretch.append(np.linalg.norm(x, axis=1) - u)
        strain = stretch[-1] / u
        if scene.string.law == "slack":
            strain = np.maximum(strain, 0.0)
        elastic = 0.0 if implicit else float(np.sum(0.5 * EA * strain ** 2 * u))
        potential = elastic - mu * g * u * float(np.sum(0.5 * (q[:-1, 2] + q[1:, 2])))
        total += 0.5 * h * (t0 - potential)
    if implicit:
        mean = 0.5 * (stretch[0] + stretch[1])
        if scene.string.law == "slack":
            mean = np.maximum(mean, 0.0)
        total -= h * float(np.sum(EA / (l0 + l1) * n * mean ** 2))  # EA/(2 ubar) sbar^2, ubar = (l0 + l1)/(2N)
    return total


def winch_lagrangian(l0, l1, convective=True):
    """L_d(scene, r, R, dr, FmI) of a step reeling from l0 to l1 [m]: :func:`winch_string_lagrangian`
    plus the body's and a free pivot's terms, which the winch does not change."""
    def L(scene, r, R, dr, FmI):
        return (winch_string_lagrangian(scene, r, dr, l0, l1, convective)
                + rigid_body_lagrangian(scene, r[-1], R, dr[-1], FmI) + pivot_lagrangian(scene, r[0], dr[0]))
    return L


# -- rotations -----------------------------------------------------------------------------------
def hat(v) -> np.ndarray:
    """``hat(v) @ y == v x y``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def expm_minus_identity(w) -> np.ndarray:
    """exp(w^) - I by Rodrigues' formula, sin(t)/t w^ + 2 sin^2(t/2)/t^2 w^ w^, t = |w|, with no
    cancellation for small t."""
    t = float(np.linalg.norm(w))
    W = hat(w)
    if t == 0.0:
        return np.zeros((3, 3))
    return np.sin(t) / t * W + 2.0 * (np.sin(0.5 * t) / t) ** 2 * (W @ W)


def expm(w) -> np.ndarray:
    """exp(w^) in SO(3)."""
    return np.eye(3) + expm_minus_identity(w)


def right_perturbed(F, FmI, w):
    """F exp(w^) - I from F and F - I, without cancellation (delta F = F zeta^; also R_{k+1} ->
    R_{k+1} exp(w^) at fixed R_k)."""
    return FmI + F @ expm_minus_identity(w)


def left_perturbed(F, FmI, w):
    """exp(w^) F - I from F and F - I, without cancellation (R_k -> R_k exp(-w^) at fixed
    R_{k+1} turns F = R_k^T R_{k+1} into exp(w^) F)."""
    return FmI + expm_minus_identity(w) @ F


def random_rotation(rng, max_angle=np.pi) -> np.ndarray:
    """A rotation about a random axis by an angle uniform in [max_angle/10, max_angle] [rad]."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    return expm(axis * rng.uniform(0.1 * max_angle, max_angle))


# -- scenes and states for the tests ------------------------------------------------------------
def cylinder_inertia_about(mass, a, b, height, rho_c) -> np.ndarray:
    """Inertia [kg m^2] of a solid elliptic cylinder (semi-axes a, b along body e1, e2 [m], axis
    along e3) about a point at -rho_c from its centre of mass (body frame):
    J = J_cm + M (|rho_c|^2 I - rho_c rho_c^T),  J_cm = M diag(b^2/4 + H^2/12, a^2/4 + H^2/12, (a^2 + b^2)/4).
    """
    rho = np.asarray(rho_c, dtype=float)
    J_cm = mass * np.diag([b * b / 4 + height ** 2 / 12, a * a / 4 + height ** 2 / 12, (a * a + b * b) / 4])
    return J_cm + mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))


#: The paper's cylinder (0.1 kg, 0.06/0.04/0.1 m) hung from a lug 0.13 m from its centre: a larger
#: rho_c than the paper's and the inertia of the actual body (~1e-3 kg m^2, erratum 6).
GEOMETRIC_RHO_C = (0.10, 0.04, 0.08)
GEOMETRIC_OVERRIDES = dict(
    rho_c=list(GEOMETRIC_RHO_C),
    J=cylinder_inertia_about(0.1, 0.06, 0.04, 0.1, GEOMETRIC_RHO_C).tolist(),
)


def random_nodes(scene, rng, stretch=(0.8, 1.25)) -> np.ndarray:
    """Nodes (N+1, 3) [m]: a random walk from the pivot roughly along e1 whose element lengths are
    uniform in ``stretch`` times u (so elements are stretched and compressed)."""
    n, u = scene.string.elements, scene.string.u
    d = np.array([1.0, 0.0, 0.0]) + 0.5 * rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    steps = d * (u * rng.uniform(*stretch, size=n))[:, None]
    return np.asarray(scene.pivot.position, dtype=float) + np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])


def random_state(scene, rng, speed=0.5, spin=2.0):
    """A perturbed discrete state: :func:`random_nodes`, node velocities uniform in +-speed [m/s]
    (the pivot's too when it is free), a random attitude, Omega uniform in +-spin [rad/s];
    momenta by the continuous Legendre transform of the finite-element Lagrangian (any momenta
    would do for these tests)."""
    from esp_gym.physics.simulator import State, legendre_momenta

    r = random_nodes(scene, rng)
    v = rng.uniform(-speed, speed, size=r.shape)
    if not scene.pivot.is_free:
        v[0] = 0.0
    R = random_rotation(rng)
    p, Pi = legendre_momenta(scene, r, v, R, rng.uniform(-spin, spin, size=3))
    return State(r, p, R, Pi, 0)
