"""The application: commands, runs, sweeps, evaluation, figures, studies and result files. Nothing in the core below it imports it; stages never do (import-linter contracts)."""
