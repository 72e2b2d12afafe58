"""``python -m recon``: the ``recon`` command.

That command is built on top of :mod:`recon.cli` by :mod:`chain.cli` (its ``example`` and
``batch`` also clone motion, which needs :mod:`fmc`); this launcher is the one file under
``recon/`` that names it, and no module of ``recon`` imports it.
"""

from chain.cli import recon_main

recon_main()
