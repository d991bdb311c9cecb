"""The lumped-mass scene as a MuJoCo model: point masses on slide joints joined by tendon springs.

An optional comparison (``pip install esp_gym[bench]``): ``mujoco`` is imported on first use only.

With ``string.mass_model: lumped`` our discrete model is a chain of point masses and springs, so
MuJoCo can integrate exactly the same ordinary differential equation. The Lagrangian (lumped
version of the paper's finite-element Lagrangian, docs/physics.md "Conventions") is

    L = sum_a (m_a/2) |v_a|^2 + (M/2) |v_N|^2 + (1/2) Omega.J Omega + M v_N . R (Omega x rho_c)
        + g sum_a m_a (r_a . e3) + M g (r_N + R rho_c) . e3 - sum_a (kappa/2) (|r_{a+1} - r_a| - u)^2

with nodes r_0 (pivot) .. r_N (attachment point, the body-frame origin), m_a = m for interior
nodes and m/2 for the end nodes (m = mu u, kappa = EA/u), J about the attachment point. The
MJCF below reproduces each term:

* interior node a (1..N-1): a body at the world origin with three slide joints along e1, e2, e3,
  so its qpos is r_a itself and it has no rotational freedom (an exact point mass m); its
  rotational inertia is a placeholder (MuJoCo requires one) that no joint can excite;
* the load: one free-joint body whose frame origin is the attachment point, carrying the body
  (M, centre of mass rho_c) and the attachment node's lumped m/2 at its origin: mass
  M + m/2, centre of mass c = M rho_c / (M + m/2), inertia about c
  J - (M + m/2)(|c|^2 I - c c^T) (J is about the origin, where the point mass adds nothing);
* a free pivot (``pivot.kind: free``): node 0 as a point mass M_p + m/2 on slide joints; a fixed
  pivot is a world site (its m/2 never moves: it adds the constant -g (m/2) r_0 . e3 to the
  energy, which :meth:`MujocoChain.total_energy` puts back);
* element a: a spatial tendon between the sites of nodes a and a+1 with stiffness kappa and
  springlength u (``law: elastic``, two-sided) or springlength ``0 u`` (``law: slack``: MuJoCo's
  dead band [0, u] gives no force when compressed, which is the tension-only law);
* gravity (0, 0, +g): our e3 points down; contacts and constraints disabled, no damping.

State conventions (checked in tests/test_mujoco_chain.py): slide-joint qpos/qvel are the node's
spatial position [m] and velocity [m/s]; the free joint's qpos is (attachment point [m],
quaternion (w, x, y, z) of R, body -> world), its qvel is (velocity of the attachment point in
the world frame [m/s], angular velocity in the BODY frame [rad/s]) -- the body-frame Omega of
the paper. After ``mj_step`` the derived quantities (``xpos``, ``site_xpos``, ``energy``) are not
those of the new state (Euler: the state before the step; RK4: its last stage): read positions
from qpos, and run ``mj_forward`` before reading
the energy (as :meth:`MujocoChain.total_energy` does).
"""
from __future__ import annotations

import numpy as np

from ..extras import require
from ..scene.params import Scene

#: MuJoCo's names of its integrators (``<option integrator=...>``); all but RK4 are first order.
#: With no damping, implicit and implicitfast still differ from Euler (semi-implicit) once the
#: load turns: the paper example's load hardly turns over 1 s and their errors agree to 4 digits
#: there; large_offset's spins, and they do not. "discrete" needs MuJoCo >= 3.13.
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast", "discrete")

#: Rotational inertia [kg m^2] given to the point-mass node bodies: MuJoCo requires a positive
#: one, and with slide joints only no force can rotate them, so its value never enters.
_NODE_INERTIA = 1e-9


def import_mujoco():
    """The ``mujoco`` module, or an ImportError that names the ``bench`` extra."""
    return require("mujoco", "the MuJoCo comparison (esp_gym.verify.mujoco_chain)")


def _num(x: float) -> str:
    """A float for MJCF, to the last bit (repr round-trips)."""
    return repr(float(x))


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def load_inertial(scene: Scene) -> tuple[float, np.ndarray, np.ndarray]:
    """``(mass [kg], centre of mass (3,) [m], inertia about it (3, 3) [kg m^2])`` of the load
    body with the attachment node's lumped string mass m/2 at its origin (body frame)."""
    M = scene.body.mass
    mt = M + 0.5 * scene.string.m
    c = M * np.asarray(scene.body.rho_c, dtype=float) / mt
    J = scene.body.J
    Jc = 0.5 * (J + J.T) - mt * (c @ c * np.eye(3) - np.outer(c, c))
    return mt, c, Jc


def chain_xml(scene: Scene, integrator: str = "RK4", h: float | None = None) -> str:
    """MJCF of ``scene`` (lumped mass) as a point-mass chain; ``h`` [s] defaults to ``scene.h``."""
    if scene.string.mass_model != "lumped":
        raise ValueError("the MuJoCo chain is the lumped-mass model: load the scene with "
                         "string={'mass_model': 'lumped'}")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
    st = scene.string
    n, m = st.elements, st.m
    g = scene.gravity
    h = scene.h if h is None else float(h)
    r = scene.initial_nodes()
    R0 = np.array(scene.initial.R0, dtype=float)
    mt, c, Jc = load_inertial(scene)
    small = _num(_NODE_INERTIA)
    spring = _num(st.u) if st.law == "elastic" else f"0 {_num(st.u)}"

    def point_mass(a: int, mass: float) -> str:
        joints = "".join(f'<joint name="node{a}_{ax}" type="slide" axis="{axis}"/>'
                         for ax, axis in (("x", "1 0 0"), ("y", "0 1 0"), ("z", "0 0 1")))
        return (f'    <body name="node{a}">{joints}'
                f'<inertial pos="0 0 0" mass="{_num(mass)}" diaginertia="{small} {small} {small}"/>'
                f'<site name="s{a}"/></body>')

    bodies = []
    if scene.pivot.is_free:
        bodies.append(point_mass(0, scene.pivot.mass + 0.5 * m))
        pivot_site = ""
    else:
        pivot_site = f'    <site name="s0" pos="{_vec(r[0])}"/>'
    bodies += [point_mass(a, m) for a in range(1, n)]
    # MuJoCo's fullinertia order: ixx iyy izz ixy ixz iyz
    full = (Jc[0, 0], Jc[1, 1], Jc[2, 2], Jc[0, 1], Jc[0, 2], Jc[1, 2])
    bodies.append(
        f'    <body name="load" pos="{_vec(r[n])}" quat="{_vec(quaternion(R0))}"><freejoint name="load"/>'
        f'<inertial pos="{_vec(c)}" mass="{_num(mt)}" fullinertia="{_vec(full)}"/><site name="s{n}"/></body>')
    tendons = [f'    <spatial name="element{a}" stiffness="{_num(st.kappa)}" springlength="{spring}">'
               f'<site site="s{a}"/><site site="s{a + 1}"/></spatial>' for a in range(n)]
    lines = [
        f'<mujoco model="{scene.name}_lumped_chain">',
        '  <compiler inertiafromgeom="false"/>',
        f'  <option timestep="{_num(h)}" integrator="{integrator}" gravity="0 0 {_num(g)}">',
        '    <flag contact="disable" constraint="disable"/>',
        '  </option>',
        '  <worldbody>',
        *([pivot_site] if pivot_site else []),
        *bodies,
        '  </worldbody>',
        '  <tendon>',
        *tendons,
        '  </tendon>',
        '</mujoco>',
    ]
    return "\n".join(lines)


def quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), MuJoCo's order, of the rotation matrix ``R`` (body -> world)."""
    q = np.empty(4)
    import_mujoco().mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


class MujocoChain:
    """A compiled MuJoCo model of a lumped-mass scene and its data.

    >>> chain = MujocoChain(load_scene("paper_example", string={"mass_model": "lumped"}), "RK4", h=1e-4)
    >>> chain.step(100)                # 100 MuJoCo steps in one C call
    >>> chain.attachment_position(), chain.total_energy()
    >>> chain.reset()                  # back to the scene's initial state

    ``model`` and ``data`` are MuJoCo's ``MjModel`` and ``MjData``; ``xml`` the MJCF they came from.
    """

    def __init__(self, scene: Scene, integrator: str = "RK4", h: float | None = None):
        mujoco = import_mujoco()
        self.scene = scene
        self.integrator = integrator
        self.xml = chain_xml(scene, integrator, h)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self.h = float(self.model.opt.timestep)
        m = self.model
        n = scene.string.elements
        first = 0 if scene.pivot.is_free else 1
        #: qpos and qvel address of each point-mass node (its x slide joint; y, z follow)
        self.node_qpos = {a: int(m.jnt_qposadr[m.joint(f"node{a}_x").id]) for a in range(first, n)}
        self.node_qvel = {a: int(m.jnt_dofadr[m.joint(f"node{a}_x").id]) for a in range(first, n)}
        self.load_qpos = int(m.jnt_qposadr[m.joint("load").id])
        self.load_qvel = int(m.jnt_dofadr[m.joint("load").id])
        self.load_body = int(m.body("load").id)
        # a fixed pivot's m/2 is not in the MuJoCo model: its constant gravity potential [J]
        self.energy_offset = 0.0 if scene.pivot.is_free else (
            -scene.gravity * 0.5 * scene.string.m * float(scene.initial_nodes()[0, 2]))
        self.qpos0, self.qvel0 = initial_qpos_qvel(self)
        self.reset()

    def reset(self) -> None:
        """``mj_resetData``, then the scene's initial state (:func:`initial_qpos_qvel`)."""
        import_mujoco().mj_resetData(self.model, self.data)
        self.data.qpos[:] = self.qpos0
        self.data.qvel[:] = self.qvel0

    def step(self, nstep: int = 1) -> None:
        """``nstep`` MuJoCo steps of ``h`` in one call."""
        import_mujoco().mj_step(self.model, self.data, nstep=int(nstep))

    def attachment_position(self) -> np.ndarray:
        """Attachment point r_N (3,) [m] of the current state (read from qpos: valid after mj_step)."""
        return self.data.qpos[self.load_qpos:self.load_qpos + 3].copy()

    def node_positions(self) -> np.ndarray:
        """Node positions r_0..r_N (N+1, 3) [m] of the current state (from qpos)."""
        r = np.empty((self.scene.string.elements + 1, 3))
        r[0] = self.scene.initial_nodes()[0]  # a fixed pivot; overwritten when free
        for a, i in self.node_qpos.items():
            r[a] = self.data.qpos[i:i + 3]
        r[-1] = self.attachment_position()
        return r

    def total_energy(self) -> float:
        """Kinetic + gravitational + elastic energy [J] of the current state, on esp_gym's zero:
        MuJoCo's energy (``mj_forward``, then ``mj_energyPos``/``mj_energyVel``: valid after
        ``mj_step`` and without the energy flag) plus the fixed pivot's constant m/2 term."""
        mujoco = import_mujoco()
        m, d = self.model, self.data
        mujoco.mj_forward(m, d)
        mujoco.mj_energyPos(m, d)
        mujoco.mj_energyVel(m, d)
        return float(d.energy[0] + d.energy[1]) + self.energy_offset

    def samples(self, t_final: float, every: int) -> np.ndarray:
        """Run from the current state for ``t_final`` [s], a whole number of ``every``-step
        blocks of one ``mj_step`` call each; attachment positions (K+1, 3) [m] at the start and
        after each block."""
        nsteps = int(round(t_final / self.h))
        if nsteps % every or abs(nsteps * self.h - t_final) > 1e-9 * max(1.0, t_final):
            raise ValueError(f"t_final = {t_final} s is not a whole number of {every} steps of h = {self.h} s")
        out = np.empty((nsteps // every + 1, 3))
        out[0] = self.attachment_position()
        mj_step = import_mujoco().mj_step
        m, d, a = self.model, self.data, self.load_qpos
        for k in range(1, len(out)):
            mj_step(m, d, nstep=every)
            out[k] = d.qpos[a:a + 3]
        return out

    def warnings(self) -> int:
        """Number of MuJoCo warnings raised so far (a bad qacc, qpos or qvel makes MuJoCo reset
        the state silently: a run with warnings has failed)."""
        return int(sum(w.number for w in self.data.warning))


def initial_qpos_qvel(chain: MujocoChain) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos, qvel)`` of the scene's initial state for ``chain.model``: node positions [m] and
    velocities [m/s] (``scene.initial_nodes()``, ``scene.initial_velocities()``) in the slide
    joints; in the free joint the attachment point, the quaternion (w, x, y, z) of R0, the
    attachment velocity (world frame) and Omega0 (body frame: MuJoCo's free-joint convention
    and the paper's alike)."""
    scene = chain.scene
    qpos = chain.model.qpos0.copy()
    qvel = np.zeros(chain.model.nv)
    r = scene.initial_nodes()
    v = scene.initial_velocities()
    for a, i in chain.node_qpos.items():
        qpos[i:i + 3] = r[a]
    for a, i in chain.node_qvel.items():
        qvel[i:i + 3] = v[a]
    i, j = chain.load_qpos, chain.load_qvel
    n = scene.string.elements
    qpos[i:i + 3] = r[n]
    qpos[i + 3:i + 7] = quaternion(np.array(scene.initial.R0, dtype=float))
    qvel[j:j + 3] = v[n]
    qvel[j + 3:j + 6] = scene.initial.Omega0
    return qpos, qvel
