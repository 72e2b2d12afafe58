"""Moving heads: facial motion cloning, FAT authoring, FAP streams and playback.

``fmc`` imports :mod:`mpeg4` and never :mod:`recon`.
"""
