"""A small catalogue of real parts: reference data of the FESTO DMSP-20 fluidic muscle and its fit."""
