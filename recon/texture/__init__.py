"""The head's texture from the two photos, and its texture coordinates.

The stages, each a module:

- :mod:`~recon.texture.cameras`: each photo's camera from the head's 3D feature points and
  the marked pixels;
- :mod:`~recon.texture.delight`: each photo's light fitted on the head's normals and
  divided out (the albedo);
- :mod:`~recon.texture.warp`: the side photo warped along the feature line onto the front
  photo's frame (Lee and Magnenat-Thalmann);
- :mod:`~recon.texture.lines`: the lines along which the photos' layers meet;
- :mod:`~recon.texture.regions`: which photo each part of the skin takes;
- :mod:`~recon.texture.blend`: the Burt–Adelson multiresolution spline that merges the
  layers;
- :mod:`~recon.texture.skin`: the whole skin texture and its coordinates
  (:func:`texture_skin`, :func:`textured_head`);
- :mod:`~recon.texture.bake`, :mod:`~recon.texture.materials`, :mod:`~recon.texture.atlas`:
  texture-space rasterising, the eyes', teeth's and tongue's textures, and an xatlas re-pack.
"""

from .blend import blend_feather, blend_hard, blend_multiband, seam_band, seam_gradient
from .lines import feature_line, line_depth, line_ids
from .regions import (FOLD, FRONT, HIDDEN, MIRRORED, REGIONS, SEEN, feature_polygon, split_by_region,
                      triangle_regions, vertex_regions)
from .skin import SkinTexture, photo_background, texture_skin, textured_head
from .warp import FEATURE_LINE, FeatureLineWarp

__all__ = ["FEATURE_LINE", "REGIONS", "FRONT", "SEEN", "MIRRORED", "HIDDEN", "FOLD", "FeatureLineWarp", "SkinTexture",
           "line_ids", "feature_line", "feature_polygon", "line_depth", "vertex_regions", "triangle_regions",
           "split_by_region", "blend_multiband", "blend_hard", "blend_feather", "seam_band", "seam_gradient",
           "photo_background", "texture_skin", "textured_head"]
