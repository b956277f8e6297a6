"""The exchange between the physics (:mod:`bfsitl.physics`) and a SITL firmware.

* :mod:`bfsitl.sim.fdm_encoding`: a sensor reading as the fdm packet one generation reads;
* :mod:`bfsitl.sim.bridge`: the paced UDP bridge for stock builds (fdm out, motors in);
* :mod:`bfsitl.sim.lockstep`: one reply per packet for lockstep builds, stepped in the
  caller's thread;
* :mod:`bfsitl.sim.clock_lock` and :mod:`bfsitl.sim.health`: keeping a stock SITL's clock on
  simulated time, and watching that it does.
"""
