"""Export: what leaves Python. A scenario turned into something that runs outside frogsim.

This layer sits above the engines (software in the loop runs them as the plant) and below the
command line. It holds:

* :mod:`frogsim.export.board`: the Arduino Mega 2560's facts (pins read from the Arduino AVR
  core; the ATmega2560's memories and ADC timing from :mod:`frogsim.components.atmega2560`);
* :mod:`frogsim.export.emulator`: simavr's ATmega2560 driven in lockstep from Python (analog
  inputs, driven pins, timed pin changes, the serial port's bytes, the data memory);
* :mod:`frogsim.export.sketch`: the firmware plan (:mod:`frogsim.control.firmware`: each
  controller kind's law as C, from the kind's own module) as an Arduino sketch with its runtime
  (timer interrupt, conversions, valve pins, overrun counter, serial log), and its build;
* :mod:`frogsim.export.sil`: software in the loop, the built firmware on the emulated board
  against the model, checked sample by sample against the model's compiled law;
* :mod:`frogsim.export.serial_log`: the firmware's serial log as a CSV trace (from the emulated
  board, or from a real one through pyserial) that ``frogsim fit`` reads.

Later: co-simulation units (the circuit as a unit another simulator steps).
"""
