"""All CLI sub-commands, one module each; add new ones to COMMANDS.

Each entry is (name, module, attribute, short help). The group imports a command's module
only when that command runs (or its own ``--help`` is asked for), so that ``guardid --help``
and a mistyped command answer without importing numpy or scipy. The short help here is what
``guardid --help`` lists; a test checks that it equals each command's own docstring line.
"""

COMMANDS = [
    ("simulate", "guardid.commands.simulate", "simulate",
     "Closed-loop PID run of the simulated robot; write true and sensed signals to CSV."),
    ("excite", "guardid.commands.excite", "excite",
     "Write an excitation trajectory YAML; print its condition number and limit use."),
    ("capture", "guardid.commands.capture", "capture",
     "Run the trajectory on the robot in closed loop and record telemetry to OUTPUT."),
    ("identify", "guardid.commands.identify", "identify",
     "Identify the robot's base parameters and motor constants from LOG [LOG ...]."),
    ("validate", "guardid.commands.identify", "validate",
     "Score parameter sets on runs LOG [LOG ...]: torque prediction error, all joints stacked."),
    ("doctor", "guardid.commands.doctor", "doctor",
     "Check a robot on the bench: wiring, sensors, link, watchdog, e-stop; one verdict each."),
    ("fake-port", "guardid.commands.fake_port", "fake_port",
     "Serve the emulated robot on a pseudo-terminal until SIGINT/SIGTERM."),
    ("flash", "guardid.commands.flash", "flash",
     "Build the AVR firmware for ROBOT, flash and verify it, check INFO's firmware id."),
    ("ports", "guardid.commands.ports", "ports",
     "List serial ports; warn when a USB-serial adapter's latency timer is above 2 ms."),
    ("reproduce", "guardid.commands.reproduce", "reproduce",
     "Simulate EXPERIMENT, run the estimators, print our numbers beside the paper's."),
    ("export", "guardid.commands.export", "export",
     "Write the identified robot (PARAMS from identify --consistent) as URDF and/or MJCF."),
    ("convert", "guardid.commands.convert", "convert",
     "Write the capture log LOG as an MCAP file for Foxglove and PlotJuggler."),
]  # fmt: skip
