"""The simulator's built-in campaign profiles (YAML), read by :mod:`ofbe_data.simulator.config`.

Data only: nothing to import.
"""
