"""mlr: recorded missions -> datasets -> torch networks the UAV managers fly (see mlr/README.md)."""
