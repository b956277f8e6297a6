"""``bfsitl log replay``: a real flight's blackbox log flown again through the real firmware.

The log's header becomes the replaying FC's settings (:mod:`.header_settings`), its sticks
are streamed into a lockstep SITL on simulated time with a vehicle profile
(:mod:`.sticks`, :mod:`.flight`), and the two logs are compared per axis (:mod:`.compare`,
:mod:`.step_response`).
"""
