"""config_from_dict: nested configs by mapping or dotted keys, and the errors it raises."""

import dataclasses

import pytest

from exobench.core import ConfigError, UnknownNameError, check_range
from exobench.core.pipeline import config_from_dict


@dataclasses.dataclass(frozen=True)
class Band:
    band_m: float = 0.1
    rings: int = 4

    def __post_init__(self) -> None:
        check_range("band_m", self.band_m, 0.0, 1.0)


@dataclasses.dataclass(frozen=True)
class Stage:
    kind: str = "none"
    band: Band = Band()


@dataclasses.dataclass(frozen=True)
class Top:
    voxel_m: float = 0.5
    n: int = 3
    stage: Stage = Stage(kind="band", band=Band(band_m=0.2))


def test_flat_values_are_converted():
    assert config_from_dict(Top, {"voxel_m": "0.25", "n": "7"}) == Top(voxel_m=0.25, n=7)


def test_dotted_keys_reach_any_depth_over_the_nested_default():
    got = config_from_dict(Top, {"stage.band.rings": "9", "n": 2})
    assert got == Top(n=2, stage=Stage(kind="band", band=Band(band_m=0.2, rings=9)))


def test_nested_mapping_equals_dotted_keys():
    a = config_from_dict(Top, {"stage": {"kind": "x", "band": {"band_m": "0.05"}}})
    b = config_from_dict(Top, {"stage.kind": "x", "stage.band.band_m": "0.05"})
    expected = Top(stage=Stage(kind="x", band=Band(band_m=0.05, rings=4)))
    assert a == b == expected


def test_asdict_of_the_result_is_the_complete_config():
    got = config_from_dict(Top, {"stage.band.band_m": 0.3})
    assert dataclasses.asdict(got) == {
        "voxel_m": 0.5, "n": 3, "stage": {"kind": "band", "band": {"band_m": 0.3, "rings": 4}},
    }  # fmt: skip


def test_a_config_instance_may_be_given_whole():
    band = Band(band_m=0.4)
    assert config_from_dict(Stage, {"band": band}) == Stage(band=band)


@pytest.mark.parametrize(
    ("values", "path"),
    [({"nope": 1}, "nope"), ({"stage.nope": 1}, "stage.nope"), ({"stage.band.nope": 1}, "stage.band.nope"),
     ({"stage": {"band": {"nope": 1}}}, "stage.band.nope"), ({"n.x": 1}, "n.x")],
)  # fmt: skip
def test_unknown_keys_at_any_depth_name_the_dotted_path(values, path):
    with pytest.raises(UnknownNameError) as e:
        config_from_dict(Top, values, prefix="pipe.")
    assert e.value.name == path
    assert "pipe parameter" in str(e.value)


@pytest.mark.parametrize("raw", ["abc", 3, 0.5])
def test_a_plain_value_for_a_whole_nested_config_is_a_config_error(raw):
    with pytest.raises(ConfigError) as e:
        config_from_dict(Top, {"stage": raw}, prefix="pipe.")
    assert e.value.field == "pipe.stage"


@pytest.mark.parametrize("raw", ["inf", "-inf", "nan", float("inf"), "1.5", "x"])
def test_ints_refuse_non_integers_with_a_config_error(raw):
    with pytest.raises(ConfigError) as e:
        config_from_dict(Top, {"stage.band.rings": raw})
    assert e.value.field == "stage.band.rings"


def test_a_nested_range_error_names_the_dotted_field():
    with pytest.raises(ConfigError) as e:
        config_from_dict(Top, {"stage.band.band_m": "2"}, prefix="pipe.")
    assert e.value.field == "pipe.stage.band.band_m"


def test_kiss_icp_filter_stage_is_nested():
    from exobench.mapping.odometry.kiss_icp import KissConfig
    from exobench.perception.lidar_filter import FilterStageConfig, NaiveGroundConfig

    got = config_from_dict(KissConfig, {"filter.kind": "naive-ground", "filter.naive_ground.ground_margin_m": "0.1"})
    expected = KissConfig(filter=FilterStageConfig(kind="naive-ground", naive_ground=NaiveGroundConfig(ground_margin_m=0.1)))
    assert got == expected
    assert config_from_dict(KissConfig, {}) == KissConfig()
    with pytest.raises(ConfigError):
        config_from_dict(KissConfig, {"filter.kind": "median"})
