"""Timing within the joints' limits (issue 16, section 4).

``limits``: the nine axes' speed and acceleration limits of the job's robot. ``path``: a stroke's joint path
time-optimal under those limits and a gun-tip speed bound per segment (toppra), checked densely and
tightened until the limits hold everywhere. ``moves``: point-to-point moves (transfers, station moves),
time-optimal under the same limits (ruckig). ``stage``: the plan's time stamps, achievable speeds, the real
cycle time and the time factors the film takes from them.
"""
