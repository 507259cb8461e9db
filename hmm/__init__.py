"""Multiscale (FEMxDEM) coupling: a scikit-fem macro problem with DEM micro models.

The macro solver, micro models and farms arrive with the multiscale issues; the package
exists now so that the distribution installs both import packages.
"""

__all__ = []
