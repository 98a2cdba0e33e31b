"""Bridges to other tracking frameworks.

:mod:`jointtrack.interop.stonesoup`
    Stone Soup data associators on jointtrack's exact engine (``JPDAExact``,
    ``JPDALBP``) and converters between Stone Soup objects and jointtrack's
    arrays. Needs the ``stonesoup`` extra: ``pip install 'jointtrack[stonesoup]'``.

Nothing here is imported by ``import jointtrack``; each bridge imports its
framework only when it is itself imported.
"""
