"""A datagram whose FCS this process computed in Python (:func:`mlink_sim.wire.frame.with_fcs`, pure cores).

With the compiled cores the FCS is computed in C and ``with_fcs`` returns plain ``bytes``: checking in C costs
less than creating this object.

A module of its own: mlink_sim.wire.frame is compiled (mypyc, docs/architecture.md "Compiled cores (mypyc)"), and mypyc
cannot compile a subclass of ``bytes``; here it stays a Python class that the compiled code creates and tests for.
"""

from __future__ import annotations

__all__ = ["Sealed"]


class Sealed(bytes):
    """A datagram :func:`with_fcs` made in this process: its FCS was computed over these very bytes, and bytes do
    not change, so :func:`fcs_ok` (and :func:`decode`) know it is right without computing it again. In the virtual
    clock's in-memory network a datagram reaches its receiver as the object its sender made, so the FCS is
    computed once per datagram, not twice; a datagram read from a socket, or changed on the way (an impairment
    copies what it corrupts), is plain ``bytes`` and checked in full. It is ``bytes`` in every other respect."""

    __slots__ = ()
