"""Export: what leaves Python. A scenario turned into something that runs outside frogsim.

This layer sits above the engines (it may run a scenario to compare against) and below the
command line. It holds, so far, the board the firmware is for and an emulation of it:

* :mod:`frogsim.export.board`: the Arduino Mega 2560's facts (pins read from the Arduino AVR
  core, memories) and the ATmega2560's ADC conversion timing, with the plan that fits a control
  period's conversions or refuses with the arithmetic;
* :mod:`frogsim.export.emulator`: simavr's ATmega2560 driven in lockstep from Python (analog
  inputs, driven pins, timed pin changes, the serial port's bytes).

It is where these go next:

* firmware for the robot's microcontroller (an ATmega2560): each controller kind's law as C code
  (the kind's own module under :mod:`frogsim.control` holds it), a sketch that samples the
  sensors and drives the valves at the scenario's controller rate, and its build;
* software in the loop: that firmware run on an emulated board against the model, and the board's
  serial log read back into a trace that compares with the model's compiled controller (the same
  valves commanded at the same samples);
* later, co-simulation units (the circuit as a unit another simulator steps).
"""
