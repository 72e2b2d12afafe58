"""Facial Animation Tables for any head with feature points: FaceEngine's hybrid muscle model.

Where a head has feature points but no sculpted shapes, its motion comes from a model of
the face placed from those points (Fratarcangeli and Schaerf's FaceEngine [1]_):

- a **parametric layer**: the jaw turns about the axis through the two jaw pivots, with
  full weight over the lower face and a cosine fade across the angular sector
  Vchin–Vpivot–Vneck; each eyelid turns about its lid axis; each eyeball about its centre,
  found as the midpoint of its two farthest vertices; the head about 7.1, faded linearly
  between the upper and lower neck lines;
- **Waters muscles** [2]_: linear muscles (a cone of influence about the line from the bone
  attachment to the skin insertion, angular and radial cosine fall-offs, Waters's skin
  elasticity k) and a sphincter for the mouth, placed from the feature points by
  ``fmc/data/muscles.toml``;
- the **combination rule** of [1]_: in the four groups forehead left/right and mouth
  up/down the displacement of a vertex takes the direction of the summed displacements
  of the group's muscles and the largest single magnitude; other muscles add up;
- the **upper/lower split**: the skin is labelled upper or lower by a flood fill that
  grows from the upper-lip and the lower-lip feature points at once (each vertex goes to
  the front that reaches it first along the mesh's edges), so the lips, which touch,
  stay apart; the jaw and the lower-face muscles act only on lower vertices.

:func:`author_from_muscles` turns the model into FATs: each low-level FAP is mapped to
the model by fitting non-negative muscle contractions (or the parametric angle) so that
its feature point moves along the FAP's axis by ``value × FAPU`` while unrelated points
stay still; FAPs no muscle serves (tongue, ears, the nose tip, puffed cheeks, lips pushed
forward) fall back to the local displacement field of :mod:`fmc.author`.
:func:`author_high_level_from_muscles` evaluates the model on the FAP combinations of
``fmc/data/high_level_faps.toml`` for the visemes and expressions.

References
----------
.. [1] M. Fratarcangeli, M. Schaerf, "Realistic modeling of animatable faces in MPEG-4",
   Computer Animation and Social Agents (CASA), 2004.
.. [2] K. Waters, "A muscle model for animating three-dimensional facial expression",
   SIGGRAPH 1987, Computer Graphics 21(4), 17–24.
"""

from .authoring import HIGH_LEVEL_FAPS, author_from_muscles, author_high_level_from_muscles
from .placement import GROUPS, Muscle, load_placement, place_muscles
from .rig import FapAction, MuscleRig, eyeball_centre, split_lips

__all__ = ["GROUPS", "Muscle", "MuscleRig", "FapAction", "load_placement", "place_muscles", "split_lips",
           "eyeball_centre", "author_from_muscles", "author_high_level_from_muscles", "HIGH_LEVEL_FAPS"]
