"""Export: what leaves Python. A scenario turned into something that runs outside frogsim.

This layer sits above the engines (it may run a scenario to compare against) and below the
command line. It is empty for now; it is where these go:

* firmware for the robot's microcontroller (an ATmega2560): each controller kind's law as C code
  (the kind's own module under :mod:`frogsim.control` holds it), a sketch that samples the
  sensors and drives the valves at the scenario's controller rate, and its build;
* software in the loop: that firmware run on an emulated board against the model, and the board's
  serial log read back into a trace that compares with the model's compiled controller (the same
  valves commanded at the same samples);
* later, co-simulation units (the circuit as a unit another simulator steps).
"""
