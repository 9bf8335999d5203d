"""The paper's prediction study on the F-8 model of SINDy-MPC (``f8_recovery``'s optimum;
settings in ``configs/_function_predict.py``)."""

from configs._function_predict import predict_config

CONFIG = predict_config("f8", "f8_recovery")
