"""
Posture detection: raw sensor streams -> one posture per dwell.

Start at ``dwell_detector`` (the settled detector).

* ``dwell_detector``: each stream judged settled on its own readings.
* ``stream_lane``: one stream on the detector's time grid.
* ``robust_stats``: robust levels, spreads, level shifts, spike-rejected means.
* ``clock_offset``: a stream's clock offset from the starts of moves.
* ``turn_history``: the device turns carried by inclinometer messages.
* ``vocabulary``: the detector's words: states, settings, detected postures.
* ``stream_synchronizer``: the collector's input synchroniser (stamps, staleness).
"""
