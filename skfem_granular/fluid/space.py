"""The Taylor-Hood P2/P1 discretisation of one mesh.

:class:`TaylorHood` owns the DOF numbering, the scikit-fem bases (built when
asked for), the constant blocks (``M``, ``K`` in both viscous forms, ``B``), the
convection kernel and the DOF maps of the named boundaries. It is built once per
mesh and shared by the steady and unsteady solvers and by the force evaluation.
"""

from __future__ import annotations

import dataclasses
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementTriP1, ElementTriP2, ElementVector, FacetBasis, MeshTri, asm
from skfem.assembly import Dofs
from skfem.quadrature import get_quadrature

from . import forms
from .convection import Convection, ConvectionKernel, element_pattern
from .numbering import Numbering, facet_dofs, reference_doflocs
from .ordering import element_incidence, fill_reducing_ordering

#: How the built-in blocks can be assembled (:class:`TaylorHood`'s ``assembly``).
ASSEMBLIES = ("compiled", "scikit-fem")

#: Quadrature order shared by all bases: the convection integrand on affine
#: P2 has degree 5, the mass matrix degree 4.
INTORDER = 5


class TaylorHood:
    """P2 velocity / P1 pressure spaces and the constant blocks on ``mesh``.

    Parameters
    ----------
    mesh : skfem.MeshTri
        Triangle mesh with named boundaries (``mesh.boundaries``).
    intorder : int, optional
        Quadrature order used for every basis.
    assembly : {"compiled", "scikit-fem"}
        How the built-in blocks (``M``, ``K``, ``B``, ``Mp``, the convection) are
        assembled, on this mesh and on its moved copies: by the compiled kernels
        (:mod:`~skfem_granular.fluid.geometry`, the default) or by scikit-fem's ``asm``
        of :mod:`~skfem_granular.fluid.forms` (:mod:`~.forms_assembly`; the same
        matrices to round-off, on the same patterns; slower).

    Attributes
    ----------
    ub, pb, sb : skfem.Basis
        Vector P2, P1 pressure and scalar P2 bases (same quadrature), built on first
        use: the solvers need only the DOF numbering, and the bases' values at every
        quadrature point are the largest arrays of a space (100 MB at 95k DOFs).
    velocity_dofs, pressure_dofs, scalar_dofs : skfem.assembly.Dofs
        The DOF numbering of those three elements (``element_dofs``, ``N``,
        ``get_facet_dofs``), the same as the bases'.
    nu, np_ : int
        Number of velocity and pressure DOFs; the unknown vector is
        ``x = [u, p]`` of length ``nu + np_``.
    """

    def __init__(self, mesh: MeshTri, intorder: int = INTORDER, assembly: str = "compiled"):
        if not isinstance(mesh, MeshTri):
            raise ValueError(f"mesh: a skfem.MeshTri is required, got {type(mesh).__name__}")
        if assembly not in ASSEMBLIES:
            raise ValueError(f"assembly = {assembly!r}: must be one of {ASSEMBLIES}")
        self.assembly = assembly
        self.mesh = mesh
        self.intorder = intorder
        self.velocity_dofs = Dofs(mesh, ElementVector(ElementTriP2()))
        self.pressure_dofs = Dofs(mesh, ElementTriP1())
        self.scalar_dofs = Dofs(mesh, ElementTriP2())
        self.nu = self.velocity_dofs.N
        self.np_ = self.pressure_dofs.N
        self.N = self.nu + self.np_
        self._viscous_forms: set[str] = set()  # the viscous forms asked for (see K)

    def __repr__(self) -> str:
        return (f"TaylorHood(P2/P1 on {self.mesh.p.shape[1]} vertices, {self.mesh.t.shape[1]} "
                f"triangles: {self.nu} velocity + {self.np_} pressure = {self.N} unknowns)")

    @cached_property
    def _bases(self) -> tuple[Basis, Basis, Basis]:
        # the scikit-fem bases are built only when something asks for them
        ub = Basis(self.mesh, ElementVector(ElementTriP2()), intorder=self.intorder)
        return ub, ub.with_element(ElementTriP1()), ub.with_element(ElementTriP2())

    @property
    def has_bases(self) -> bool:
        """Whether the scikit-fem bases are built (see :meth:`release_bases`)."""
        return "_bases" in self.__dict__

    def release_bases(self) -> None:
        """Forget the scikit-fem bases and what is built on them (rebuilt at the next use).

        Their quadrature values are the largest arrays a space can hold (measured: ~1.4 GB
        at 300k unknowns, more than the step's factorisation); a user of them that runs
        once in a while (a VTU frame) releases them so that they do not stay for the
        mesh's lifetime."""
        for name in ("_bases", "_scalar_mass_lu"):
            self.__dict__.pop(name, None)

    @property
    def ub(self) -> Basis:
        """The velocity basis (``ElementVector(ElementTriP2())``), built at first use."""
        return self._bases[0]

    @property
    def pb(self) -> Basis:
        """The pressure basis (``ElementTriP1()``), built at first use."""
        return self._bases[1]

    @property
    def sb(self) -> Basis:
        """A scalar P2 basis (vorticity, streamfunction), built at first use."""
        return self._bases[2]

    @property
    def reference(self) -> TaylorHood:
        """The space whose connectivity and DOF numbering this one shares: itself, or for a
        moved space (:meth:`moved`) the space on the mesh as built. (Not stored on the space
        itself: a self-reference would keep every discretisation, with its blocks, alive
        until Python's cyclic garbage collector runs, long after a remesh dropped it.)"""
        return self.__dict__.get("_reference", self)

    # the same discretisation on a moved mesh (ALE) --------------------------
    @cached_property
    def reference_blocks(self):
        """Reference-element data that build the blocks of moved meshes (:meth:`moved`)."""
        from .geometry import ReferenceBlocks

        return ReferenceBlocks(self.reference)

    def moved(self, p: np.ndarray) -> TaylorHood:
        """This discretisation on the same mesh with its vertices moved to ``p`` ``(2, nv)``.

        Connectivity, DOF numbering, boundary DOFs and sparsity patterns are shared
        with the reference space; ``M``, ``K``, ``B``, the convection kernel and the DOF
        locations are those of the moved triangles, built from reference-element data
        (:mod:`~skfem_granular.fluid.geometry`), not by scikit-fem's ``asm``. The
        scikit-fem bases of the moved mesh are built only when something asks for them
        (output, interpolation).

        Raises
        ------
        ValueError
            When a triangle is inverted or degenerate at ``p``.
        """
        ref = self.reference
        p = np.ascontiguousarray(p, dtype=float)
        if p.shape != ref.mesh.p.shape or not np.all(np.isfinite(p)):
            raise ValueError(f"p: must be finite vertex positions of shape {ref.mesh.p.shape}")
        rb = ref.reference_blocks
        rb.check(p)  # raises on an inverted triangle
        # an alternative constructor: __init__ would number the DOFs again, which a moved
        # space shares with its reference
        new = TaylorHood.__new__(TaylorHood)
        d = new.__dict__
        # the reference's triangles as they are (sorted once when it was built)
        mesh = dataclasses.replace(ref.mesh, doflocs=p, sort_t=False)
        d.update(mesh=mesh, intorder=ref.intorder, assembly=ref.assembly,
                 nu=ref.nu, np_=ref.np_, N=ref.N, _reference=ref, reference_blocks=rb)
        for topo in ("velocity_dofs", "pressure_dofs", "scalar_dofs", "component",
                     "all_boundary_dofs", "incidence", "p1_to_p2"):
            d[topo] = getattr(ref, topo)
        return new

    @cached_property
    def _moved_geometry(self) -> dict:
        """A moved space's ``M``, ``B``, the triangles' affine maps (for the convection
        kernel) and ``K`` in the viscous forms asked of the reference space so far
        (:meth:`K`), built together on first use: every step on a moving mesh needs
        them."""
        forms_in_use = tuple(f"K_{v}" for v in sorted(self.reference._viscous_forms))
        return self.reference_blocks.moved(self.mesh.p, check=False,
                                           parts=("M", "B", "convection") + forms_in_use)

    def _geometric_block(self, name: str):
        """A geometric block of this space (moved or not), from reference-element data: one
        compiled pass over the triangles instead of scikit-fem's ``asm`` of
        :mod:`~skfem_granular.fluid.forms` (the same matrices to 1e-13, tested; a remesh
        builds them for every new mesh). With ``assembly="scikit-fem"``: ``asm`` of the form
        (:func:`~.forms_assembly.block`)."""
        if self.assembly == "scikit-fem":
            from .forms_assembly import block

            return block(self, name)
        # a moved space builds its blocks together (a viscous form nobody asked for before
        # is built on its own)
        if self.reference is not self and name in self._moved_geometry:
            return self._moved_geometry[name]
        return self.reference_blocks.moved(self.mesh.p, check=False, parts=(name,))[name]

    def blocks(self, names: tuple[str, ...]) -> tuple[sp.csr_matrix, ...]:
        """Some geometric blocks, without building the others on a moved space.

        Parameters
        ----------
        names : tuple of str
            Of ``"M"``, ``"K_symmetric"``, ``"K_laplace"``, ``"B"``.

        Returns
        -------
        tuple of scipy.sparse.csr_matrix
            The blocks in the order asked: on a moved space that has not built its
            blocks yet, from one pass over the triangles of just those (the same
            matrices as :attr:`M`, :attr:`B`, ... bit for bit: each is accumulated on
            its own, in the same order); on any other space the blocks themselves.

        Raises
        ------
        ValueError
            For a name not among the four.
        """
        known = ("M", "K_symmetric", "K_laplace", "B")
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ValueError(f"names: {unknown[0]!r} is not a geometric block; "
                             f"allowed: {', '.join(known)}")
        if (self.assembly == "scikit-fem" or self.reference is self
                or "_moved_geometry" in self.__dict__):
            return tuple(getattr(self, name) for name in names)
        built = self.reference_blocks.moved(self.mesh.p, check=False, parts=names)
        return tuple(built[name] for name in names)

    # unknowns per element, for fill-reducing orderings -------------------
    @cached_property
    def incidence(self) -> sp.csr_matrix:
        """Element-to-unknown incidence ``(nelements, N)`` of ``x = [u, p]``."""
        return element_incidence([self.velocity_dofs.element_dofs,
                                  self.pressure_dofs.element_dofs + self.nu], self.N)

    def ordering(self, columns: sp.spmatrix | np.ndarray, method: str = "minimum_degree"
                 ) -> np.ndarray:
        """Fill-reducing ordering of a system whose unknowns derive from ``x``.

        Parameters
        ----------
        columns : ndarray or sparse matrix
            Indices of the unknowns of ``x`` kept in the system (free DOFs), or
            a prolongation ``(N, n)`` from the system's unknowns to ``x``
            (eliminated and rigid-body unknowns).
        method : str
            One of :data:`.ordering.ORDERINGS`.

        Returns
        -------
        ndarray
            Permutation of the system's unknowns (:func:`.ordering.fill_reducing_ordering`).
        """
        if sp.issparse(columns):
            inc = self.incidence.astype(float) @ abs(sp.csr_matrix(columns))
        else:
            inc = self.incidence[:, np.asarray(columns)]
        centroids = self.mesh.p[:, self.mesh.t].mean(axis=1)
        return fill_reducing_ordering(inc, centroids, method)

    # constant blocks, assembled on first use ------------------------------
    @cached_property
    def M(self) -> sp.csr_matrix:
        """Velocity mass matrix ``(u, v)``."""
        return self._geometric_block("M")

    @cached_property
    def K_symmetric(self) -> sp.csr_matrix:
        """``2 (eps(u), eps(v))``; multiply by the viscosity."""
        return self._geometric_block("K_symmetric")

    @cached_property
    def K_laplace(self) -> sp.csr_matrix:
        """``(grad u, grad v)``; multiply by the viscosity."""
        return self._geometric_block("K_laplace")

    @cached_property
    def B(self) -> sp.csr_matrix:
        """Divergence block ``-(q, div u)``, shape ``(np_, nu)``."""
        return self._geometric_block("B")

    @cached_property
    def Mp(self) -> sp.csr_matrix:
        """Pressure mass matrix."""
        if self.assembly == "scikit-fem":
            return asm(forms.pressure_mass, self.pb).tocsr()
        return self.reference_blocks.pressure_mass(self.mesh.p)  # from the determinants

    @cached_property
    def Lp(self) -> sp.csr_matrix:
        """Pressure Laplacian (for the Cahouet-Chabard preconditioner)."""
        return asm(forms.pressure_laplace, self.pb).tocsr()

    @cached_property
    def convection(self) -> Convection:
        """Fast convection evaluation on this mesh (``asm`` of the forms with
        ``assembly="scikit-fem"``: :class:`~.forms_assembly.FormsConvection`)."""
        if self.assembly == "scikit-fem":
            from .forms_assembly import FormsConvection

            return FormsConvection(self)
        if self.reference is not self:
            kernel = self.reference.convection
            # a moved space has its reference's assembly: "compiled", so a kernel
            assert isinstance(kernel, ConvectionKernel)
            return kernel.with_maps(self._moved_geometry["maps"])
        rb = self.reference_blocks
        maps = rb.moved(self.mesh.p, check=False, parts=("convection",))["maps"]
        return ConvectionKernel(self.scalar_dofs.element_dofs, maps,
                                (rb.phi, rb.dphi, rb.weights), pattern=self.velocity_pattern)

    @cached_property
    def velocity_pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(slot, indices, indptr)``: the CSR pattern of the velocity blocks (``M``, ``K``,
        the convection's Jacobian: every element's 12 x 12 couplings) and the slot of each
        local entry (:func:`~skfem_granular.fluid.convection.element_pattern`)."""
        if self.reference is not self:
            return self.reference.velocity_pattern
        return element_pattern(self.scalar_dofs.element_dofs)

    def K(self, viscous: str) -> sp.csr_matrix:
        """Unit-viscosity viscous block of the given form (``"symmetric"``/``"laplace"``).

        The form is remembered by the reference space, so that moved spaces build it in
        the same pass as their other blocks."""
        if viscous in ("symmetric", "laplace"):
            self.reference._viscous_forms.add(viscous)
        if viscous == "symmetric":
            return self.K_symmetric
        if viscous == "laplace":
            return self.K_laplace
        raise ValueError(f"viscous = {viscous!r}: must be 'symmetric' or 'laplace'")

    # DOF maps --------------------------------------------------------------
    def boundary_names(self) -> list[str]:
        """Names of the mesh's named boundaries."""
        return list((self.mesh.boundaries or {}).keys())

    def check_boundary(self, name: str, field: str = "velocity") -> None:
        """Raise a clear error when ``name`` is not a boundary of the mesh."""
        names = self.boundary_names()
        if name not in names:
            raise ValueError(f"{field}[{name!r}]: no such boundary; the mesh has {names}")

    def boundary_dofs(self, name: str) -> np.ndarray:
        """Velocity DOFs (both components) on boundary ``name``, sorted."""
        self.check_boundary(name, "boundary")
        ref = self.reference
        return facet_dofs(ref.velocity_dofs, ref.mesh, ref.mesh.boundaries[name])

    def pressure_boundary_dofs(self, name: str) -> np.ndarray:
        """Pressure DOFs on boundary ``name``."""
        ref = self.reference
        return facet_dofs(ref.pressure_dofs, ref.mesh, ref.mesh.boundaries[name])

    @cached_property
    def all_boundary_dofs(self) -> np.ndarray:
        """Velocity DOFs on the whole boundary of the mesh."""
        return np.sort(self.velocity_dofs.get_facet_dofs(self.mesh.boundary_facets()).all())

    def vertex_field(self, v: np.ndarray) -> np.ndarray:
        """Velocity DOFs ``(nu,)`` of the piecewise-linear vector field with vertex values
        ``v`` ``(2, nv)`` (a mesh velocity: the vertices' motion, linear on each triangle)."""
        P = self.p1_to_p2
        out = np.empty(self.nu)
        out[0::2] = P @ v[0]
        out[1::2] = P @ v[1]
        return out

    @cached_property
    def velocity_doflocs(self) -> np.ndarray:
        """Coordinates ``(2, nu)`` of each velocity DOF."""
        if self.reference is self:
            return reference_doflocs(self.mesh, ElementVector(ElementTriP2()),
                                     self.velocity_dofs)
        # affine triangles: P2 nodes are vertices and edge midpoints, linear in the vertices
        P = self.p1_to_p2
        out = np.empty((2, self.nu))
        for c in range(2):
            out[c, 0::2] = out[c, 1::2] = P @ self.mesh.p[c]
        return out

    def numbering(self, field: str) -> Numbering:
        """The element, DOF numbering and DOF locations of the scalar P2 (``"scalar"``) or
        the pressure (``"pressure"``) field, as a scikit-fem basis of this mesh has them,
        without building one (its quadrature values cost ~20 ms at 20k nodes): what
        :func:`~skfem_granular.fluid.points.evaluation_matrix` reads, and ``doflocs``."""
        if field == "scalar":
            return Numbering(ElementTriP2(), self.scalar_dofs, self.mesh)
        if field == "pressure":
            return Numbering(ElementTriP1(), self.pressure_dofs, self.mesh)
        raise ValueError(f"field = {field!r}: must be 'scalar' or 'pressure'")

    @cached_property
    def quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference quadrature points ``(2, nq)`` and weights ``(nq,)`` of every basis."""
        return get_quadrature(self.mesh.refdom, self.intorder)

    @cached_property
    def component(self) -> np.ndarray:
        """Component (0 = x, 1 = y) of each velocity DOF."""
        # scikit-fem numbers a vector element's DOFs component-interleaved: 2 k + c
        return (np.arange(self.nu) % 2).astype(np.int8)

    def facet_basis(self, name: str, element: str = "velocity") -> FacetBasis:
        """A facet basis on boundary ``name`` (velocity or pressure element)."""
        self.check_boundary(name, "boundary")
        elem = ElementVector(ElementTriP2()) if element == "velocity" else ElementTriP1()
        return FacetBasis(self.mesh, elem, facets=self.mesh.boundaries[name],
                          intorder=self.intorder)

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Split ``x = [u, p]`` into its velocity and pressure parts."""
        return x[: self.nu], x[self.nu :]

    # field conversions -----------------------------------------------------
    @cached_property
    def p1_to_p2(self) -> sp.csr_matrix:
        """Matrix that evaluates a P1 field at the scalar P2 nodes."""
        from .points import evaluation_matrix

        ref = np.array([[0.0, 1.0, 0.0, 0.5, 0.5, 0.0],
                        [0.0, 0.0, 1.0, 0.0, 0.5, 0.5]])
        edofs = self.scalar_dofs.element_dofs  # (6, nel)
        nodes, first = np.unique(edofs.ravel(), return_index=True)
        local, cells = np.unravel_index(first, edofs.shape)
        p1 = Numbering(ElementTriP1(), self.pressure_dofs)
        E = evaluation_matrix(p1, cells, ref[:, local])
        out = sp.csr_matrix((self.scalar_dofs.N, self.np_))
        out = E[np.argsort(nodes)] if nodes.size == self.scalar_dofs.N else out
        return sp.csr_matrix(out)

    @cached_property
    def _scalar_mass_lu(self):
        import scipy.sparse.linalg as spla

        from .forms import pressure_mass

        return spla.splu(asm(pressure_mass, self.sb).tocsc())

    def vorticity(self, u: np.ndarray) -> np.ndarray:
        """L2 projection of ``dv/dx - du/dy`` onto the scalar P2 space."""
        from skfem import LinearForm

        @LinearForm
        def curl_form(v, w):
            G = w["u"].grad
            return (G[1, 0] - G[0, 1]) * v

        rhs = asm(curl_form, self.sb, u=self.ub.interpolate(u))
        return self._scalar_mass_lu.solve(rhs)
