"""A team of strings on one body: the assembled step (step.py), the other strings' stacked rows
(arrays.py), the drones (drones.py), the winches (winch.py), the slack switch (switch.py), the run
loop (loops.py), the read-out (readout.py), the task (task.py) and the team environment's entry
points (env.py)."""
