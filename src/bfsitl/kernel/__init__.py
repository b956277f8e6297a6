"""The optional compiled kernel: the same physics and lockstep step as the pure-Python
reference, in C, with bit-identical results.

Pure Python stays the reference (``bfsitl.physics``, ``bfsitl.sim.lockstep``); the kernel is
a second implementation of its hot path for lockstep flights, built on first use with the
machine's C compiler (:mod:`bfsitl.kernel.compiler`) and chosen with ``--physics-kernel``
(``SessionConfig.physics_kernel``).  Its parity tests compare every float of every step with
the reference.
"""
