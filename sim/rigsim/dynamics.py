"""Linear state-space model of the rig and its exact modal solution.

The rig is a set of point masses (nodes) joined by spring-dampers, plus the Maxwell arms of the
specimens, each carrying its arm force as a state:

- table ``s``: mass ``M_s``, suspension ``K_s, C_s`` to the frame (or ground), shaker force
  ``F_e`` on it (and ``-F_e`` on the frame, which carries the shaker body);
- disc ``v``: mass ``M_v``, load cell ``K_c`` to the table (with a rigid link, ``v`` *is* ``s``:
  the degree of freedom is removed exactly and the disc mass is added to the table);
- device: static spring, dashpot and Maxwell arms between disc and frame, all scaled by the
  modulus factor (drift, amplitude dependence);
- fixture modes: masses on spring-dampers attached to the disc;
- frame ``g`` (optional): mass on its isolators to ground.

State ``z = [x (nodes), v (nodes), f (arm forces), conditioning filters]``, ``ż = A z + b F_e``.
Output rows give the four channels in engineering units (N, m/s², N, m/s²) as ``y = C z + d F_e``,
and the displacement across the specimens ``x_v - x_g``.

A channel whose conditioning filters (``[sensors.<channel>]`` of the rig file) adds one state per
first-order filter: a high-pass ``iω/(iω + ω_h)`` (a charge amplifier) is the transducer's
signal minus its low-passed copy ``w``, ``ẇ = ω_h (y - w)``; a low-pass ``ω_l/(iω + ω_l)`` (an
anti-alias filter, a cable) is a state ``u``, ``u̇ = ω_l (y_h - u)``, read as the channel. The
filters start at rest with the structure and carry their transients from point to point.

With the eigen-decomposition ``A = V Λ V⁻¹`` everything the measurement needs is elementwise in
the modal coordinates ``q = V⁻¹ z``; see :class:`ModalSystem`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rigsim.materials import state_model
from rigsim.rigfile import Rig

__all__ = ["CHANNEL_NAMES", "ModalSystem", "StateSpace", "build_state_space"]

CHANNEL_NAMES = ("excitation_force", "table_acceleration", "device_force", "disc_acceleration")

#: Condition number of the eigenvector matrix beyond which the modal solution is not trusted.
MAX_EIGENVECTOR_CONDITION = 1e10


@dataclass(frozen=True)
class StateSpace:
    """``ż = A z + b F_e``; channels ``y = C z + d F_e``; ``x_v - x_g = r z``."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    relative_displacement: np.ndarray


@dataclass
class _Network:
    """The rig as lumped masses, springs and dampers between nodes (node 0 the table), with
    what the device's output row needs: its spring and dashpot, its Maxwell arms, the fixture
    modes' springs and dampers on the disc."""

    n: int
    disc: int
    fixture_nodes: list[int]
    frame: int | None
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    device_k: float = 0.0
    device_c: float = 0.0
    arm_k: np.ndarray = field(default_factory=lambda: np.zeros(0))
    arm_c: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fixture_k: list[float] = field(default_factory=list)
    fixture_c: list[float] = field(default_factory=list)

    @classmethod
    def nodes_of(cls, rig: Rig) -> _Network:
        """The nodes: table, disc (behind a load cell only), fixture masses, frame."""
        names = ["table"]
        if rig.device is not None and rig.load_cell is not None:
            names.append("disc")
        disc = names.index("disc") if "disc" in names else 0
        fixture_nodes = []
        for index in range(len(rig.fixtures)):
            fixture_nodes.append(len(names))
            names.append(f"fixture{index}")
        frame = None
        if rig.frame is not None:
            frame = len(names)
            names.append("frame")
        n = len(names)
        return cls(n, disc, fixture_nodes, frame, np.zeros(n), np.zeros((n, n)),
                   np.zeros((n, n)))

    def connect(self, i: int, j: int | None, k: float, c: float) -> None:
        """Spring-damper between node i and node j (None: ground)."""
        for matrix, value in ((self.stiffness, k), (self.damping, c)):
            matrix[i, i] += value
            if j is not None:
                matrix[j, j] += value
                matrix[i, j] -= value
                matrix[j, i] -= value


def build_state_space(rig: Rig, modulus_scale: float = 1.0, time_shift: float = 1.0,
                      added_stiffness_n_per_m: float = 0.0,
                      added_damping_ns_per_m: float = 0.0) -> StateSpace:
    """State-space matrices of a rig, with K* multiplied by ``modulus_scale``, every relaxation
    time of the material (dashpot and arms) multiplied by ``time_shift`` (the temperature's
    ``a_T``), and a spring and dashpot added in parallel with the specimens (the filler
    network of a Payne effect)."""
    net = _Network.nodes_of(rig)
    _assemble(net, rig, modulus_scale, time_shift, added_stiffness_n_per_m,
              added_damping_ns_per_m)
    a, b, arm_rows = _state_matrices(net)
    c, d, relative = _outputs(net, rig, a, b, arm_rows)
    return _with_conditioning(StateSpace(a=a, b=b, c=c, d=d, relative_displacement=relative),
                              rig)


def _assemble(net: _Network, rig: Rig, modulus_scale: float, time_shift: float,
              added_stiffness_n_per_m: float, added_damping_ns_per_m: float) -> None:
    """Masses, springs and dampers of the table, the device, the fixtures and the frame."""
    disc, frame, mass = net.disc, net.frame, net.mass
    table = rig.table
    mass[0] += table.mass_kg
    net.connect(0, frame, table.stiffness_n_per_m, table.damping_ns_per_m)
    if rig.device is not None:
        mass[disc] += rig.device.mass_kg
        if rig.load_cell is not None:
            net.connect(0, disc, rig.load_cell.stiffness_n_per_m, 0.0)
        material = state_model(rig.device.material)
        net.device_k = (modulus_scale * material.static_stiffness_n_per_m
                        + added_stiffness_n_per_m)
        net.device_c = (modulus_scale * time_shift * material.damping_ns_per_m
                        + added_damping_ns_per_m)
        net.arm_k = modulus_scale * material.arm_stiffness_n_per_m
        net.arm_c = modulus_scale * time_shift * material.arm_damping_ns_per_m
        net.connect(disc, frame, net.device_k, net.device_c)
    for node, mode in zip(net.fixture_nodes, rig.fixtures, strict=True):
        w_n = 2.0 * np.pi * mode.frequency_hz
        k_f = mode.mass_kg * w_n**2
        c_f = 2.0 * mode.damping_ratio * mode.mass_kg * w_n
        mass[node] += mode.mass_kg
        net.connect(node, disc, k_f, c_f)
        net.fixture_k.append(k_f)
        net.fixture_c.append(c_f)
    if frame is not None and rig.frame is not None:
        w_g = 2.0 * np.pi * rig.frame.frequency_hz
        mass[frame] += rig.frame.mass_kg
        net.connect(frame, None, rig.frame.mass_kg * w_g**2, 2 * rig.frame.damping_ratio *
                    rig.frame.mass_kg * w_g)


def _state_matrices(net: _Network) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, arm rows)``: positions, velocities, then one force state per Maxwell arm."""
    n, disc, frame = net.n, net.disc, net.frame
    arm_k, arm_c = net.arm_k, net.arm_c
    n_arms = arm_k.size
    size = 2 * n + n_arms
    a = np.zeros((size, size))
    b = np.zeros(size)
    inv_mass = 1.0 / net.mass
    a[:n, n : 2 * n] = np.eye(n)
    a[n : 2 * n, :n] = -inv_mass[:, None] * net.stiffness
    a[n : 2 * n, n : 2 * n] = -inv_mass[:, None] * net.damping
    # Arm i pulls the disc back with its force f_i and pushes the frame with it.
    arm_rows = np.arange(2 * n, size)
    if n_arms:
        a[n + disc, arm_rows] -= inv_mass[disc]
        if frame is not None:
            a[n + frame, arm_rows] += inv_mass[frame]
        a[arm_rows, n + disc] = arm_k
        if frame is not None:
            a[arm_rows, n + frame] = -arm_k
        a[arm_rows, arm_rows] = -arm_k / arm_c
    b[n] = inv_mass[0]
    if frame is not None:
        b[n + frame] = -inv_mass[frame]
    return a, b, arm_rows


def _outputs(net: _Network, rig: Rig, a: np.ndarray, b: np.ndarray, arm_rows: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(C, D, relative displacement row)``: force, table acceleration, device force, disc
    acceleration; the displacement across the specimens."""
    n, disc, frame = net.n, net.disc, net.frame
    size = a.shape[0]
    c = np.zeros((4, size))
    d = np.zeros(4)
    d[0] = 1.0  # the force transducer reads the shaker force
    c[1] = a[n]
    d[1] = b[n]
    relative = np.zeros(size)
    if rig.device is not None:
        c[3] = a[n + disc]
        d[3] = b[n + disc]
        # F_v = M_v a_v - (forces of the device and fixtures on the disc); for a finite load
        # cell this equals K_c (x_s - x_v), for a rigid link it is the force the link carries.
        on_disc = np.zeros(size)
        on_disc[disc] -= net.device_k
        on_disc[n + disc] -= net.device_c
        if frame is not None:
            on_disc[frame] += net.device_k
            on_disc[n + frame] += net.device_c
        on_disc[arm_rows] -= 1.0
        for node, k_f, c_f in zip(net.fixture_nodes, net.fixture_k, net.fixture_c,
                                  strict=True):
            on_disc[node] += k_f
            on_disc[disc] -= k_f
            on_disc[n + node] += c_f
            on_disc[n + disc] -= c_f
        c[2] = rig.device.mass_kg * c[3] - on_disc
        d[2] = rig.device.mass_kg * d[3]
        relative[disc] = 1.0
        if frame is not None:
            relative[frame] = -1.0
    return c, d, relative


def _with_conditioning(space: StateSpace, rig: Rig) -> StateSpace:
    """``space`` with a state per conditioning filter, its channel rows reading the filter."""
    a, b, c, d = space.a, space.b, space.c.copy(), space.d.copy()
    for channel, conditioning in enumerate(rig.sensors.conditioning):
        for kind, corner_hz in (("highpass", conditioning.highpass_hz),
                                ("lowpass", conditioning.lowpass_hz)):
            if corner_hz is None:
                continue
            rate = 2.0 * np.pi * corner_hz
            size = a.shape[0]
            grown = np.zeros((size + 1, size + 1))
            grown[:size, :size] = a
            # new state s: ṡ = rate (y - s) with y = c z + d F, the channel's present reading
            grown[size, :size] = rate * c[channel]
            grown[size, size] = -rate
            b = np.append(b, rate * d[channel])
            c = np.hstack([c, np.zeros((4, 1))])
            if kind == "highpass":  # the channel reads y - s
                c[channel, size] = -1.0
            else:  # the channel reads s
                c[channel] = 0.0
                c[channel, size] = 1.0
                d[channel] = 0.0
            a = grown
    relative = np.zeros(a.shape[0])
    relative[: space.relative_displacement.size] = space.relative_displacement
    return StateSpace(a=a, b=b, c=c, d=d, relative_displacement=relative)


class ModalSystem:
    """Eigen-decomposition of a :class:`StateSpace` and the closed forms built on it.

    For a source force ``F(τ) = Re(F̂ e^{iωτ})`` (τ from the start of a point):

    - steady state, modal: ``q_ss(τ) = ½ (p⁺ F̂ e^{iωτ} + p⁻ conj(F̂) e^{-iωτ})`` with
      ``p± = b̃ / (±iω - λ)``, ``b̃ = V⁻¹ b``;
    - solution: ``q(τ) = q_ss(τ) + e^{λτ} (q(0) - q_ss(0))`` elementwise;
    - channel phasor (steady) ``H(ω) F̂`` with ``H = C̃ p⁺ + d``, ``C̃ = C V``.
    """

    def __init__(self, space: StateSpace) -> None:
        self.space = space
        eigenvalues, vectors = np.linalg.eig(space.a)
        condition = np.linalg.cond(vectors)
        if not np.isfinite(condition) or condition > MAX_EIGENVECTOR_CONDITION:
            raise ValueError(
                f"rig model is (nearly) defective: eigenvector condition {condition:.3g}"
            )
        self.eigenvalues = eigenvalues
        self.vectors = vectors
        self.inverse = np.linalg.inv(vectors)
        self.b_modal = self.inverse @ space.b
        self.c_modal = space.c @ vectors
        self.relative_modal = space.relative_displacement @ vectors

    def to_modal(self, state: np.ndarray) -> np.ndarray:
        """Modal coordinates of a real state."""
        return self.inverse @ state

    def to_state(self, modal: np.ndarray) -> np.ndarray:
        """Real state of modal coordinates."""
        return (self.vectors @ modal).real

    def free_decay(self, state: np.ndarray, duration_s: float) -> np.ndarray:
        """State after ``duration_s`` with no source."""
        return self.to_state(np.exp(self.eigenvalues * duration_s) * self.to_modal(state))
