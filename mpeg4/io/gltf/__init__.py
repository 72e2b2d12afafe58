"""glTF 2.0 binary (GLB) export and import of heads, with pygltflib.

Layout of a head file:

- one scene whose root node ``head`` carries the mesh ``head``: one primitive per part,
  in the head's part order; parts with a rotation centre (the eyeballs) are child nodes of
  their own, translated to the centre, with vertices stored relative to it, so turning the
  node turns the eye about its centre;
- one material per part (base colour, PNG base-colour texture when textured,
  double-sided); texture coordinates are stored as (u, 1 − t) because glTF puts v = 0 at
  the top of the image and this project puts t = 0 at the bottom;
- morph targets: the head's own (e.g. ARKit-named) and the Facial Animation Tables'
  mesh deformations (:func:`mpeg4.fat.fat_to_morph_targets`), as sparse accessors, named
  in ``mesh.extras.targetNames``; a primitive a target leaves still is given an accessor
  without data (zeros, as the format allows);
- ``extras["mpeg4"]`` on the root node: part list, feature point bindings (and positions,
  for people reading the JSON), FAPU in metres, which targets stand for which FAP interval,
  the FAT transforms, and the head's metadata;
- with an animation that turns the head, the head mesh is skinned: a ``shoulders`` joint
  at the neck's cut and joints at 7.1 sharing the turn, weighted per vertex so the turn
  fades over the neck as the decoder plays it (:mod:`mpeg4.neck`); the eyeballs' nodes
  hang under the ``pivot`` joint.

Reading is in :mod:`~mpeg4.io.gltf.read`, writing in :mod:`~mpeg4.io.gltf.write`; a
file's animation is evaluated as glTF defines it by :func:`~mpeg4.io.gltf.pose.posed_parts`.
"""

from .read import FORMAT_VERSION, GlbAnimation, read_glb, read_glb_animation, read_glb_feature_points
from .pose import posed_parts
from .write import write_glb

__all__ = ["write_glb", "read_glb", "FORMAT_VERSION", "GlbAnimation", "read_glb_animation", "read_glb_feature_points",
           "posed_parts"]
