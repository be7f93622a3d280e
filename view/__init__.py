"""Looking at runs: Rerun views of logs (an edge: it reads logs and depends on ``sim``, never the
reverse). ``scene`` turns a log into columns; ``rerun_view`` draws them."""
