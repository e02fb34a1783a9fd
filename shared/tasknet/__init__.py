"""Task models on Petri nets (thesis chapter 3), as pure computation.

    ptnet.py      the typed net (places, transitions, arcs), its Pre/Post/C matrices, firing
    analysis.py   reachability graph with a states cap, Karp-Miller coverability, properties
    cenet.py      condition/event nets as 1-safe P/T nets with unit weights
    pnml.py       PNML (ISO/IEC 15909-2, P/T subset) read and write
    jsonform.py   the JSON form of a net and loading a net by its file's suffix
    layout.py     a layered layout and an SVG picture of a net
    keypoints.py  key points of a sampled tool path (§3.3.3)
"""
