"""The paper's prediction study on SINDy-MPC's Lorenz system (``lorenz_switch``'s optimum;
settings in ``configs/_function_predict.py``)."""

from configs._function_predict import predict_config

CONFIG = predict_config("lorenz", "lorenz_switch")
