"""From two photos to a textured head with MPEG-4 feature points.

Stages, one module each as they land: ``landmarks`` and ``annotate`` (2D feature points),
``calibrate`` (3D points), ``deform`` (Dirichlet free-form deformation of the generic
head), ``texture``, ``build`` and ``batch`` (many heads). ``example`` runs the main job on the
embedded example; ``animatable`` is the clone step a batch row may end with. Both reach
:mod:`fmc` only when called: ``recon`` itself never imports it.
"""

__all__ = ["run_example"]


def __getattr__(name):
    # Lazy, so that importing one stage does not load the whole chain.
    if name == "run_example":
        from .example import run_example

        return run_example
    raise AttributeError(f"module 'recon' has no attribute {name!r}")
