"""Transfer alignment: the variation (slave) IMU's INS aided by the reference (master) state.

:mod:`.measurements` carries the master's velocity and attitude to the slave (nominal lever arm
and mounting) and gives the matching innovations and Jacobians; :mod:`.filter` is the
closed-loop error-state filter (the aided filter's navigation and bias states plus the mounting
misalignment and, optionally, the lever-arm error). Equations: docs/transfer_alignment.md.
"""
