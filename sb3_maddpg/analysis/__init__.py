"""What to do with a trained team: evaluate it (the paper's protocol), describe its behaviour, score it against
reference teams, inspect its critics, export its actors."""
