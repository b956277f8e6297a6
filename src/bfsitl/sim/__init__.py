"""The exchange between the physics (:mod:`bfsitl.physics`) and a SITL firmware.

* :mod:`bfsitl.sim.bridge`: the paced UDP bridge for stock builds (fdm out, motors in);
* :mod:`bfsitl.sim.lockstep`: one reply per packet for lockstep builds, stepped in the
  caller's thread;
* :mod:`bfsitl.sim.clock_lock` and :mod:`bfsitl.sim.health`: keeping a stock SITL's clock on
  simulated time, and watching that it does.

The fdm packet's encoding (:mod:`bfsitl.protocol.fdm_encoding`) and the shared-memory exchange
(:mod:`bfsitl.link.shm_exchange`) are below, where the compiled loop (:mod:`bfsitl.kernel`)
reaches them too.
"""
