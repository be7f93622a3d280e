"""Whether Parquet tables are equal to the first (pyarrow Table.equals, data and metadata)."""
import sys

import pyarrow.parquet as pq

first = pq.read_table(sys.argv[1])
for path in sys.argv[2:]:
    t = pq.read_table(path)
    print(path, "equal" if t.equals(first, check_metadata=True) else "DIFFERENT",
          "(data equal)" if t.equals(first) else "(data DIFFERENT)")
