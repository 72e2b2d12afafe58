"""The head's shape from the photos' points.

- :mod:`~recon.shape.calibrate`: 3D feature points from the points marked on a front and a
  side photo (roll, facing, height scale, size, orthographic or pinhole cameras);
- :mod:`~recon.shape.sibson`: exact Sibson natural-neighbour coordinates in 3D;
- :mod:`~recon.shape.deform`: the Dirichlet free-form deformation of the generic head (and
  a thin-plate RBF beside it for comparison);
- :mod:`~recon.shape.fit`: the two together, ``recon fit``;
- :mod:`~recon.shape.template_fit`: the generic head's skin fitted to any mesh
  (non-rigid closest-point TPS), for marking meshes.
"""
