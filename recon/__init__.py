"""From two photos to a textured head with MPEG-4 feature points.

Stages, one module each as they land: ``landmarks`` and ``annotate`` (2D feature points),
``calibrate`` (3D points), ``deform`` (Dirichlet free-form deformation of the generic
head), ``texture``, ``build`` and ``batch`` (many heads); ``example`` is the embedded
example. ``recon`` never imports :mod:`fmc`: what needs both (``recon example``'s cloning
and speech, the clone step a batch row may end with) is in :mod:`chain`.
"""
