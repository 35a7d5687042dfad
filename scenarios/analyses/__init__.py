"""Each paper's own analysis of a campaign (per-run metrics, the JSON summary, the
paper-shaped tables and its own plots), declared by its experiment in
``scenarios.experiments`` (``summarise``, ``tabulate``, ``own_plots``)."""
