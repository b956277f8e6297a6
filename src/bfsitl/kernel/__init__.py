"""The compiled code: the physics (``physics.c``, the model's only implementation), the
lockstep loop (``lockstep_loop.c``) and the blackbox frame decoder (``blackbox_frames.c``,
whose Python face is :mod:`bfsitl.blackbox.compiled_frames`), in one library built on first
use with the machine's C compiler (:mod:`bfsitl.kernel.compiler`, the compiler the firmware
build needs anyway).

A change to the model is made in ``physics.c`` (and, when it adds a parameter, in
:class:`~bfsitl.physics.QuadParams`, ``physics.h`` and :mod:`bfsitl.kernel.layout`, which a
test keeps in step with the header).  :class:`bfsitl.physics.Simulator` is the typed Python
face; :mod:`bfsitl.sim.lockstep_stepper` runs its lockstep loop for the bridge.
"""
