"""Where a flight's rows become records: one sink per file format, chosen by the file's
suffix (:mod:`bfsitl.records.sinks`), the sinks of one flight fed and closed together
(:mod:`bfsitl.records.outputs`), the CSV log (:mod:`bfsitl.records.csv_log`), the plot
(:mod:`bfsitl.records.plot`) and Foxglove's MCAP file and live server
(:mod:`bfsitl.records.foxglove`)."""
