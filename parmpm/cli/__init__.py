"""The command line: parsing, the commands, launching under MPI, benchmarks."""
