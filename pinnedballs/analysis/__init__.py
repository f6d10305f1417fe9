"""Analysis of states and runs: observables (functions of a state, and the one registry of
observables by name), and every order of collisions (`orders`)."""
