"""``recon annotate``: a local web page to place and correct the feature points of two photos
or of a head mesh.

- :mod:`~recon.annotate.placement`: where the points start (a saved file, automatic
  detection by :mod:`recon.landmarks` when installed, or the generic head fitted to the
  photos);
- :mod:`~recon.annotate.session`: the two photos and the ``fdp.json`` (validated, atomic
  saves with a backup, the 3D fit for the preview);
- :mod:`~recon.annotate.mesh_session`: the 3D mode, a head mesh and its ``fdp.json`` (points
  snapped to the surface and bound to it);
- :mod:`~recon.annotate.server`: the Starlette app on 127.0.0.1 and :func:`annotate`, which
  ``recon annotate`` runs;
- ``static/``: the page (plain ES modules; three.js bundled from npm for the 3D view).
"""

from .mesh_session import MeshSession
from .placement import initial_annotation
from .server import annotate, create_app
from .session import AnnotationSession

__all__ = ["annotate", "create_app", "AnnotationSession", "MeshSession", "initial_annotation"]
