"""Analysis of the metamaterial: linear stability of the rest state and observables of a run."""
