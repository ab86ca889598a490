# SPDX-License-Identifier: MIT
"""mcfd_client._events - the progress callback's dict, one shape for both
doors and for the in-process `mcf.smooth`: {step, t, dt, energy, volume,
phase, done}.

A step of the flow fills step, t, dt, energy and volume (phase "steps",
done None: the daemon's step events carry no share); energy (the area)
and volume are the run's step log's, so a run that keeps none gives None
(REST), 0 (gRPC WatchJob) or NaN (mcf.smooth without with_metrics): the
daemon keeps it when the request asked for the measures, and for every
streamed call (smooth with progress); one of the core's
milestones between steps (the default request's spike repair, noise
reading, set-up and passes) fills step (the steps so far), phase and done
(the job's share of work, 0..1), the others None.
"""


def step_event(step, t, dt, energy, volume):
    return {"step": step, "t": t, "dt": dt, "energy": energy, "volume": volume,
            "phase": "steps", "done": None}


def work_event(step, phase, done):
    return {"step": step, "t": None, "dt": None, "energy": None, "volume": None,
            "phase": phase, "done": done}
