"""``recon annotate``: a local web page to place and correct the feature points of two photos.

- :mod:`~recon.annotate.placement`: where the points start (a saved file, automatic
  detection by :mod:`recon.landmarks` when installed, or the generic head fitted to the
  photos);
- :mod:`~recon.annotate.session`: the two photos and the ``fdp.json`` (validated, atomic
  saves with a backup, the 3D fit for the preview);
- :mod:`~recon.annotate.server`: the Starlette app on 127.0.0.1 and :func:`annotate`, which
  ``recon annotate`` runs;
- ``static/``: the page (plain ES modules; three.js bundled from npm for the 3D view).
"""

from .placement import initial_annotation
from .server import annotate, create_app
from .session import AnnotationSession

__all__ = ["annotate", "create_app", "AnnotationSession", "initial_annotation"]
