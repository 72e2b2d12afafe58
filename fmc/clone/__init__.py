"""Facial Motion Cloning: copy a source head's morph targets and animation tables onto any
head with feature points.

The method, after Pandžić [1]_, one small function per step:

1. Normalisation (:func:`normalisation`): every vertex takes the FAPU scale of the
   region of its nearest feature points, so motion is compared in FAPU terms.
2. Facial motion: the source's morph targets (and the FAT's mesh tables as morph
   targets), divided by the source's scales.
3. Alignment space (:func:`alignment_space`): a cylindrical projection about a vertical
   axis placed so the mouth spans the same angle on both heads, angle 0 at the nose tip;
   then the feature-point alignment (:func:`align_heads`): both heads' points moved
   half-way to each other's (:func:`midway`) over a shipped triangulation of the feature
   points (:func:`load_fp_triangulation`; Delaunay as an option), the rest carried
   along by a bi-harmonic interpolation over each head's mesh (:func:`surface_warp`;
   the piecewise-affine map, :func:`warp`, as an option), the same from either side so
   that cloning A → B and B → A use one correspondence; depth scaled by the two heads'
   radii at the feature points, the depth under the outer surface
   (:func:`outer_radius`: the mouth's inside, the sockets) by their sizes. The
   interpolation holds as well the eyelid margins, the lips' inner contours and the
   mouth's corners: on each
   mesh the shortest paths along its edges between their feature points, sampled by arc
   length and moved half-way like the points (:func:`contour_pairs`). There the motion
   changes fastest, so misalignment costs most: on ICT FaceKit identities the round trip
   fell from 2.46 % to 2.29 %, source → target from 6.22 % to 6.07 %. They are left out
   where either head lacks a contour, and between meshes of unlike density (a coarse
   mesh's paths stray from the fold by up to an edge).
4. Interpolation (:func:`skin_weights`, :func:`interpolation_matrix`): each target vertex
   takes the motion of the projected source triangle that holds it, the nearest in depth
   where several do; a triangle it lies outside competes by its distance, the excess of
   negative barycentric weight clamped and renormalised (so a vertex just off its own
   surface takes that surface's motion, not the layer behind); each corner's value is
   carried half-way along its gradient (:func:`gradient_operator`), exact for quadratic
   motion.
5. Anti-aliasing, on request only: the motion averaged over a disc of samples about the
   target vertex (Epanechnikov weights). A sparse target needs none: each vertex takes the
   motion at its own place, exactly what a dense target's vertex there takes, and the
   target's linear interpolation between its vertices is the low-pass; a disc only blurs
   (figures in :func:`correspond` and ``benchmarks/clone_antialiasing.py``).
6. Lips (:func:`lip_sides`, :func:`lip_classes`, :func:`lip_sides_on_mesh`): upper-lip
   target vertices take no motion from the source's lower lip, and the other way round;
   the lips' zone is a polygon of their feature points, the side within it the lip whose
   points are nearer along the mesh.
7. Eyes, teeth, tongue and the other parts (:func:`find_parts`): found from their feature
   points; rotations about their centres (installed when missing), translations in FAPU
   terms; the FAT's eye and head rotations re-centred on the target. A target part the
   source has nothing for that lies on the skin (separate eyelids, brow and lash cards, a
   beard: :func:`surface_followers`) moves as the skin under it.
8. Denormalisation by the target's scales; :func:`clone` returns the target with the
   cloned morph targets (same names) and FATs, each low-level table scaled so that its own
   feature point moves by value × FAPU on the target (:func:`calibrate_tables`) and
   relaxed where it turns the target's skin over (:func:`fmc.unfold.unfold_tables`).

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
"""

from .align import (FPTriangulation, align_heads, bilaplacian, delaunay_fp_triangulation, folded_triangles,
                    load_fp_triangulation, midway, outer_radius, surface_warp, triangulation_for, vertex_positions, warp)
from .calibrate import LIMITS, calibrate_tables
from .cloning import REQUIRED_FPS, Correspondence, check_head, clone, clone_targets, correspond
from .contours import CONTOURS, contour_pairs, contour_path, edge_graph
from .followers import FOLLOW_ES0, follower_weights, surface_followers
from .interpolate import TriangleIndex, disc_samples, gradient_operator, interpolation_matrix
from .parts import PART_ROLES, PartRef, find_parts, rigid_motion, sphere_centre
from .regions import LIP_FPS, lip_classes, lip_sides, lip_sides_on_mesh, normalisation, region_scales
from .skin import pin_feature_points, skin_weights
from .space import MOUTH_SPAN, alignment_space, cylinder_axis

__all__ = [
    "clone", "clone_targets", "correspond", "Correspondence", "check_head", "REQUIRED_FPS",
    "calibrate_tables", "LIMITS",
    "align_heads", "lip_sides", "skin_weights", "pin_feature_points",
    "normalisation", "region_scales", "lip_classes", "lip_sides_on_mesh", "LIP_FPS",
    "alignment_space", "cylinder_axis", "MOUTH_SPAN",
    "FPTriangulation", "load_fp_triangulation", "delaunay_fp_triangulation", "triangulation_for", "vertex_positions",
    "folded_triangles", "warp", "midway", "surface_warp", "bilaplacian", "outer_radius",
    "CONTOURS", "contour_path", "contour_pairs", "edge_graph",
    "TriangleIndex", "disc_samples", "gradient_operator", "interpolation_matrix",
    "PART_ROLES", "PartRef", "find_parts", "rigid_motion", "sphere_centre",
    "FOLLOW_ES0", "follower_weights", "surface_followers",
]
