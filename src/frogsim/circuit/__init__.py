"""The pneumatic network: source, exhaust, muscles, valves, supply tubes and pump as flat arrays."""
