# SPDX-License-Identifier: MIT
"""mcfd_client._events - the progress callback's dict, one shape for both
doors and for the in-process `mcf.smooth`: {step, t, dt, energy, volume,
phase, done}.

A step of the flow fills step, t, dt, energy and volume (phase "steps",
done None: the daemon's step events carry no share); one of the core's
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
