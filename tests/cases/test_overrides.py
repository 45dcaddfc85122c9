"""--set keys: the one-line error for a key nothing takes, and the key list of fpsi list."""
from fpsi_jax import cases
from fpsi_jax.cases import overrides as ov


def test_an_unknown_key_names_the_nearest_keys_and_where_the_list_is():
    scene = cases.build("dam_break", dx=0.02)
    msg = str(ov.unknown_key("dxx", "scene 'dam_break'", ["dx", "column_width"],
                             scene.params, "dam_break"))
    assert msg == ("unknown key 'dxx' for scene 'dam_break'; did you mean 'dx'? "
                   "`fpsi list dam_break` lists the keys it takes")
    msg = str(ov.unknown_key("qqq", "scene 'dam_break'", [], scene.params, "dam_break"))
    assert "did you mean" not in msg


def test_a_scene_files_key_points_to_the_params_leaf_it_sets():
    scene = cases.build("collision")                       # discs: DemParams
    msg = str(ov.unknown_key("friction", "scene file 'a.toml'", [], scene.params, "a.toml"))
    assert "did you mean 'dem.mu'?" in msg
    # where the scene has no such leaf, no pointer to it
    fluid = cases.build("dam_break", dx=0.02)
    msg = str(ov.unknown_key("friction", "scene 'dam_break'", [], fluid.params, "dam_break"))
    assert "dem.mu" not in msg


def test_key_table_lists_builder_keys_params_and_options_with_values():
    scene = cases.build("dam_break", dx=0.02)
    lines = ov.key_table(scene, "dam_break")
    text = "\n".join(lines)
    assert "  dx                           0.005" in text          # the builder's default
    assert "  sph.dp                       0.02" in text           # the scene as built
    assert "the stability bound" in text
    assert "  x64                          false" in text
