"""Flight physics: the potential field every agent follows (:mod:`.apf`, compiled in
:mod:`._apf_kernel`), the kinematic models that limit each command (:mod:`.kinematics`), and the
fixed-wing turn-ahead guard (:mod:`.lookahead`)."""
