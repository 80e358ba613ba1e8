"""Control: gaits as data (phase timing of valves and palms) turned into valve programs and palm
commands on the controller's grid."""
