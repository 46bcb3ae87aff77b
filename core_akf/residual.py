"""Static correction of a modally reduced model: the residual flexibility of the modes it leaves
out (mode-acceleration method).

A model reduced to its lowest modes ``Phi`` (mass-normalised, physical coordinates) misses the
quasi-static response of the higher modes to the forces::

    u_res = (K^-1 - Phi Omega^-2 Phi^T) S_p f

It enters every strain and displacement output as a feed-through on the force states, so the
reduced filter sees the static deflection of the full model exactly.  :class:`StaticCorrection`
holds what that needs -- a solver for ``K^-1`` (a sparse factorisation for a large model) and the
kept modes -- and is carried by a reduced :class:`~core_akf.structure.Structure`
(``structure.static``).
"""
from __future__ import annotations

import numpy as np


class StaticCorrection:
    """Residual flexibility ``K^-1 - Phi Omega^-2 Phi^T`` of the modes a reduced model leaves out.

    Parameters
    ----------
    solve : callable -- ``solve(B)`` returns ``K^-1 B`` for a (n_phys, k) array (m/N)
    phi : ndarray (n_phys, n_kept) -- the kept mass-normalised modes in physical free DOFs
    omega : ndarray (n_kept,) -- their circular frequencies (rad/s)
    flexibility_scale : float -- multiplies ``solve`` (a model ``factor`` times stiffer: ``1 / factor``)
    """

    def __init__(self, solve, phi, omega, flexibility_scale=1.0):
        self.solve = solve
        self.phi = np.asarray(phi, float)
        self.omega = np.asarray(omega, float)
        self.flexibility_scale = float(flexibility_scale)
        self._cache = {}

    @property
    def n_phys(self):
        return self.phi.shape[0]

    def residual(self, dofs):
        """Residual displacement for unit forces at physical free DOFs.

        Parameters
        ----------
        dofs : sequence of int
            Physical free DOF indices (0-based).

        Returns
        -------
        ndarray (n_phys, len(dofs))
            m/N (cached per set of DOFs).
        """
        key = tuple(int(d) for d in dofs)
        if key not in self._cache:
            unit = np.zeros((self.n_phys, len(key)))
            unit[list(key), np.arange(len(key))] = 1.0
            full = np.asarray(self.solve(unit), float).reshape(self.n_phys, len(key))
            kept = self.phi @ (self.phi[list(key)].T / self.omega[:, None] ** 2)
            self._cache[key] = self.flexibility_scale * full - kept
        return self._cache[key]

    def scaled(self, stiffness_factor=1.0, mass_factor=1.0):
        """The correction of the model with ``K`` times ``stiffness_factor`` and ``M`` times ``mass_factor``.

        Modes ``phi / sqrt(mass_factor)``, frequencies times ``sqrt(stiffness_factor / mass_factor)``,
        ``K^-1`` over ``stiffness_factor``.

        Parameters
        ----------
        stiffness_factor, mass_factor : float

        Returns
        -------
        StaticCorrection
        """
        return StaticCorrection(self.solve, self.phi / np.sqrt(mass_factor),
                                self.omega * np.sqrt(stiffness_factor / mass_factor),
                                self.flexibility_scale / stiffness_factor)

    def keeping(self, phi, omega):
        """The correction of the same model reduced to fewer modes; the others join the residual.

        Parameters
        ----------
        phi : ndarray (n_phys, k)
            The modes it keeps now (mass-normalised).
        omega : ndarray (k,)
            Their circular frequencies (rad/s).

        Returns
        -------
        StaticCorrection
        """
        return StaticCorrection(self.solve, phi, omega, self.flexibility_scale)
