"""Which scored candidates are refitted (candidates.to_refit): the competitive ones, the two
best locations of every family, and a sensor gain on every channel that scores."""

from nlp.diagnosis.candidates import to_refit
from nlp.diagnosis.families import AddedMass, SensorGain


def test_gains_on_every_scoring_channel_and_two_locations_of_other_families():
    scored = [(6000.0, SensorGain("floor2")), (5400.0, SensorGain("floor1")),
              (5000.0, AddedMass(2)), (3000.0, AddedMass(3)), (900.0, AddedMass(1)),
              (670.0, SensorGain("floor3")), (0.0, SensorGain("floor4"))]
    chosen = [e for _, e in to_refit(scored, top=1)]
    # competitive (within 3x of the best, at most 2 x top): the two best gains
    assert chosen[:2] == [SensorGain("floor2"), SensorGain("floor1")]
    # added mass: its two best floors only; floor 1 scores but its family is full
    assert [e for e in chosen if isinstance(e, AddedMass)] == [AddedMass(2), AddedMass(3)]
    # the third gain is refitted although far below the best; a zero score is not
    gains = [e.channel for e in chosen if isinstance(e, SensorGain)]
    assert gains == ["floor2", "floor1", "floor3"]
