"""A drone at the pivot: its arrays and step (quadrotor.py), its rotors (rotors.py), the offset
hook (hook.py), its run loops (loops.py) and the environment's entry points of its rigs (env.py)."""
