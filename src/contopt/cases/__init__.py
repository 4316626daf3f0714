"""Named example problems (cases) and their runners."""
