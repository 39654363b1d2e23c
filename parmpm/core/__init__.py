"""What every layer shares: JIT flags and cache, errors, logging, collective agreement, kernel records."""
