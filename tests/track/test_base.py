def test_all_nan_appearance_row_means_no_descriptor() -> None:
    import numpy as np
    import pytest

    from studio.track.base import Observations

    app = np.array([[0.5, 0.5], [np.nan, np.nan]], np.float32)
    obs = Observations.create(0, [[0.0, 0.0], [1.0, 1.0]], appearance=app)
    assert np.isnan(obs.appearance[1]).all()
    with pytest.raises(ValueError, match="finite rows"):
        Observations.create(0, [[0.0, 0.0], [1.0, 1.0]], appearance=[[0.5, np.nan], [0.5, 0.5]])
