"""What a run reports: history, energy ledger, metrics, particle domains, connectivity."""
