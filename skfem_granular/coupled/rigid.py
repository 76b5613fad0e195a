"""What both couplings share: rigid particles as boundaries of one fluid mesh.

Particle ``k`` is the named boundary ``"particle{k}"``; its velocity DOFs
follow the rigid motion ``u = V + omega x (x - X)`` about the reference
centre ``X`` the particle had when the mesh was built (see
:mod:`skfem_granular.coupled.monolithic`). The fluid force on it is the
consistent (reaction) force, read from the momentum residual on those DOFs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..fluid.boundary import DirichletData
from ..fluid.factor_cache import FactorCache
from ..fluid.forces import rigid_lever
from ..fluid.operator import NavierStokesOperator


@dataclass(frozen=True)
class RigidBodies:
    """The particles a coupling moves, as boundaries ``"particle{k}"`` of its mesh.

    Parameters
    ----------
    centers : (2, K) array_like
        Reference centres of the particles on the mesh.
    mass, inertia : (K,) array_like
        Masses and moments of inertia per unit depth.
    imposed : (K,) array_like of bool, optional
        Particles whose motion is prescribed: their rigid velocities are given to
        each step (``StepProblem.xi_imposed``) as Dirichlet data, not solved for (with
        their rotation, whatever ``rotation`` says); the fluid force on them is reported
        as on the others. Default: none.
    rotation : bool
        Whether the free particles may rotate.
    """

    centers: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    imposed: np.ndarray | None = None
    rotation: bool = True
    K: int = field(init=False, repr=False)

    def __post_init__(self):
        K = int(np.asarray(self.mass).size)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "centers", np.asarray(self.centers, dtype=float).reshape(2, K))
        object.__setattr__(self, "mass", np.asarray(self.mass, dtype=float).reshape(K))
        object.__setattr__(self, "inertia", np.asarray(self.inertia, dtype=float).reshape(K))
        object.__setattr__(self, "imposed", np.zeros(K, dtype=bool) if self.imposed is None
                           else np.asarray(self.imposed, dtype=bool).reshape(K))
        object.__setattr__(self, "rotation", bool(self.rotation))


@dataclass(frozen=True)
class CorrectorOptions:
    """How a coupling's corrector solves: the linear solver
    (:func:`~skfem_granular.fluid.linsolve.make_solver`), the stopping tolerance of its
    iterations relative to the velocity scale, and their limit per step."""

    solver: str = "auto"
    newton_tol: float = 1e-8
    max_iterations: int = 15


class RigidParticles:
    """Common state of :class:`MonolithicCoupling` and :class:`PartitionedCoupling`.

    Parameters
    ----------
    space : TaylorHood
        Discretisation of the fluid mesh.
    fluid : Fluid
    walls : dict
        ``{boundary name: velocity spec}`` of the fixed walls.
    bodies : RigidBodies
        The particles: reference centres, masses, inertias, prescribed motions.
    convection : bool
        Navier-Stokes or unsteady Stokes.
    terms : UserTerms, optional
        scikit-fem forms added to the fluid equations
        (:class:`~skfem_granular.fluid.user_terms.UserTerms`); the consistent forces on
        the particles include them.
    """

    #: The factorisations of the step matrices (built by each coupling for its system).
    factors: FactorCache

    #: Whether a step reads the pressure at ``t_{n-1}`` (``StepProblem.p_prev``); the
    #: state carries it (and a checkpoint stores it) only for such a coupling.
    uses_pressure_history = False

    def __init__(self, space, fluid, walls: dict, bodies: RigidBodies, *,
                 convection: bool = True, terms=None):
        self.space = space
        self.fluid = fluid
        self.K = bodies.K
        self.centers = bodies.centers.copy()  # moved meshes take other centres (move())
        self.mass, self.inertia = bodies.mass, bodies.inertia
        self.rotation = bodies.rotation
        self.imposed: np.ndarray = np.asarray(bodies.imposed, dtype=bool)
        #: the particles whose rigid velocities are unknowns
        self.free_particles = np.flatnonzero(~self.imposed)
        names = [f"particle{k}" for k in range(self.K)]
        specs = dict(walls)
        specs.update({n: (0.0, 0.0) for n in names})
        # the symmetric-gradient form whatever the boundaries: the consistent force and torque
        # on a particle come from the residual tested with its rigid modes, and the Laplacian
        # form's residual misses half of a rotating particle's viscous torque
        self.op = NavierStokesOperator(space, fluid, DirichletData(space, specs),
                                       convection=convection, viscous="symmetric", terms=terms)
        self.wall_dirichlet = DirichletData(space, walls) if walls else None
        self.particle_dofs = [space.boundary_dofs(n) for n in names]
        # every particle's DOFs at once, with their particle and component: the lever arms
        # and forces of all particles in one vectorised pass (a step needs them for each)
        self._all_dofs = np.concatenate(self.particle_dofs or [np.zeros(0, dtype=np.int64)])
        self._owner = np.repeat(np.arange(self.K), [d.size for d in self.particle_dofs])
        self._all_comp = space.component[self._all_dofs]
        self.timings = {"assembly": 0.0, "factorization": 0.0, "solve": 0.0, "forces": 0.0}
        # right-hand side, solution and velocity block of the last step (for flow())
        self._last: tuple[np.ndarray, np.ndarray, sp.spmatrix | None] | None = None

    def levers(self, k: int | np.integer):
        """DOFs of particle ``k``, their components and ``e_z x (x - X)`` at them."""
        d = self.particle_dofs[k]
        return d, self.space.component[d], rigid_lever(self.space, d, self.centers[:, k])

    def all_levers(self) -> np.ndarray:
        """``e_z x (x - X_k)`` at the DOFs of every particle ``k``, concatenated in particle
        order (the values :meth:`levers` gives one particle at a time)."""
        locs = self.space.velocity_doflocs[:, self._all_dofs]
        X = self.centers[:, self._owner]
        return np.where(self._all_comp == 0, -(locs[1] - X[1]), locs[0] - X[0])

    def imposed_values(self, x: np.ndarray, xi_imposed) -> np.ndarray:
        """Write the rigid velocities ``xi_imposed`` ``(3, K)`` of the imposed particles
        onto their boundary DOFs of the full vector ``x`` (in place; returns ``x``)."""
        if xi_imposed is None:
            return x
        for k in np.flatnonzero(self.imposed):
            d, c, lever = self.levers(k)
            x[d] = np.where(c == 0, xi_imposed[0, k], xi_imposed[1, k]) + xi_imposed[2, k] * lever
        return x

    @property
    def chord_extra_iterations(self) -> int:
        """Iterations the chord operator held cost beyond fresh ones (its ledger)."""
        return self.factors.extra_iterations

    @chord_extra_iterations.setter
    def chord_extra_iterations(self, value: int) -> None:
        self.factors.extra_iterations = value

    def forget_factorization(self) -> None:
        """Factorise anew on the next step (as a coupling rebuilt from a checkpoint does)."""
        self.factors.clear()

    # ------------------------------------------------------------------ factorisations
    def factor_counts(self) -> dict:
        """Factorisations on this mesh: ``factorizations`` of the BDF2-Stokes operator and
        ``jacobian_refreshes`` (Newton Jacobians where the chord iteration stalled)."""
        return {"factorizations": self.factors.factorizations,
                "jacobian_refreshes": self.factors.refreshes}

    def inherit_factor_kind(self, old: RigidParticles) -> None:
        """Start with the kind of factorisation ``old`` (the coupling on the mesh this one
        replaces) held: a Newton Jacobian's if it held one."""
        self.factors.newton_operator = old.factors.newton_operator

    def factor_record(self) -> dict:
        """Where the factorisation held was made, for a checkpoint (``factor_a0`` None: no
        record): ``factor_a0``, the vertices ``factor_nodes`` and centres
        ``factor_centers`` of the mesh then, and for a Newton Jacobian its fluid state
        ``factor_x`` and mesh velocity ``factor_w``."""
        on = getattr(self, "factorized_on", None)
        a0 = self.factors.a0
        if a0 is None or on is None:
            a0, on = None, (None, None, None, None)
        return {"factor_a0": a0, "factor_nodes": on[0], "factor_centers": on[1],
                "factor_x": on[2], "factor_w": on[3]}

    def refactor(self, record: dict, reference_space) -> None:
        """Make again the factorisation a :meth:`factor_record` describes (a coupling on a
        moving mesh; nothing when the record is empty)."""
        if record.get("factor_a0") is not None:
            raise NotImplementedError(f"{type(self).__name__}: no factorisation on a moved mesh")

    def fluid_forces(self, Rf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Consistent force ``(2, K)`` and torque ``(K,)`` of the fluid on each particle."""
        r = Rf[self._all_dofs]
        x_comp = self._all_comp == 0
        F = -np.stack([np.bincount(self._owner, weights=np.where(x_comp, r, 0.0),
                                   minlength=self.K),
                       np.bincount(self._owner, weights=np.where(x_comp, 0.0, r),
                                   minlength=self.K)])
        T = -np.bincount(self._owner, weights=r * self.all_levers(), minlength=self.K)
        return F, T

    def held_block(self):
        """The velocity block of the factorisation held (None: none)."""
        return self.factors.A_uu

    def flow(self, x):
        """The fluid part of a coupled state as a :class:`~skfem_granular.fluid.Flow`."""
        from ..fluid.flow import Flow

        op = self.op
        rhs_u = self._last[0] if self._last else None
        A_uu = self._last[2] if self._last and self._last[2] is not None else self.held_block()
        w_mesh = getattr(self, "w_mesh", None)

        def residual_u(xx):
            return op.residual(xx, rhs_u=rhs_u, A_uu=A_uu, w_mesh=w_mesh)[: self.space.nu]

        return Flow(op, op.normalize_pressure(np.array(x, dtype=float)), residual_u)
