"""Pure physics functions, SI units, one equation of the paper per function.

Every function here is compiled with Numba (``njit``) so that the engine can inline it in its hot
loop, and stays callable from plain Python with float arguments for tests and studies.
"""
