"""The commands that chain photo-side work (``recon``) with motion (``fmc``).

``fmc`` never imports ``recon``, and ``recon`` never imports ``fmc``; what needs both lives
here, on top of them: the ``recon`` command (:mod:`recon.cli`'s commands, with ``recon
example`` running the whole chain and ``recon batch`` cloning motion onto the heads it
builds) and the ``fmc`` command (:mod:`fmc.cli`'s commands, plus ``fmc mark``, and
``fmc clone`` onto a head that has no feature points yet).
"""

from .animatable import clone_step
from .clone import clone_onto, target_head
from .example import run_example

__all__ = ["clone_onto", "clone_step", "run_example", "target_head"]
