"""The commands that chain photo-side work (``recon``) with motion (``fmc``).

``fmc`` never imports ``recon``, and ``recon`` never imports ``fmc``; what needs both lives
here, on top of them: the ``fmc`` command (``fmc.cli``'s commands, plus ``fmc mark``, and
``fmc clone`` onto a head that has no feature points yet).
"""

from .clone import clone_onto, target_head

__all__ = ["clone_onto", "target_head"]
