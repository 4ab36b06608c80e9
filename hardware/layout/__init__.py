"""Raw-recording layouts told from the data: statistics, candidate layouts scored on a file, checks."""
