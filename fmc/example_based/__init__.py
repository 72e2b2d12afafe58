"""Example-based expression cloning, after Pyun et al.

The animator's own target key-models are what the target shows; the source animation
only chooses how to blend them:

1. key-models (:mod:`.key_models`): a neutral model and verbal (visemes) and emotional
   (expressions) key-models for source and target, and a composite of every emotional ×
   verbal pair by per-vertex importance;
2. parameters (:mod:`.parameters`): about 20 feature points' displacements of a source
   face, reduced by PCA (eigenvalues above 1e-5 of the largest) to p = F v;
3. weights (:mod:`.cardinal`): a cardinal basis function per key-model over the
   parameter space, linear least squares plus radial cubic B-splines, 1 at its own
   key-model and 0 at the others;
4. run time (:mod:`.retarget`): per frame, p from the input's feature points, the
   weights w(p) and T_B + Σ w_i (T_i − T_B); whole animations in and out.

References
----------
.. [1] H. Pyun, Y. Kim, W. Chae, H. W. Kang, S. Y. Shin, "An example-based approach for
   facial expression cloning", Proc. ACM SIGGRAPH/Eurographics Symposium on Computer
   Animation (2003) 167-176.
.. [2] P.-P. Sloan, C. F. Rose, M. F. Cohen, "Shape by example", Proc. Symposium on
   Interactive 3D Graphics (2001) 135-143.
"""

from .cardinal import CardinalBasis, cubic_bspline
from .key_models import (EMOTIONAL, VERBAL, KeyModels, combined_name, composite, composite_key_models,
                         key_models_from_shapes, smooth_importance, vertex_importance)
from .parameters import FEATURE_POINTS, Parameterisation, feature_matrix, load_feature_points
from .retarget import (KEY_MODEL_SOURCES, Retargeter, read_animation, retarget, source_key_models, target_key_models,
                       write_retargeted)

__all__ = ["CardinalBasis", "cubic_bspline", "EMOTIONAL", "VERBAL", "KeyModels", "combined_name", "composite",
           "composite_key_models", "key_models_from_shapes", "smooth_importance", "vertex_importance",
           "FEATURE_POINTS",
           "Parameterisation", "feature_matrix", "load_feature_points", "KEY_MODEL_SOURCES", "Retargeter",
           "read_animation", "retarget", "source_key_models", "target_key_models", "write_retargeted"]
