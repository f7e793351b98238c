"""CPU-sized unimodal backbones (audio MFCC, video segment, RF spectrogram) with interchangeable
heads (sigmoid or evidential), and a plain seeded training loop (:mod:`evids.models.train`)."""
from __future__ import annotations

from evids.models.backbones import (
                                    AudioLeNet,
                                    RFNet,
                                    UnimodalModel,
                                    VideoNet,
                                    build_backbone,
                                    build_model,
                                    seeded_init,
)
from evids.models.train import TrainConfig, TrainResult, predict, train_model

__all__ = ["AudioLeNet", "RFNet", "TrainConfig", "TrainResult", "UnimodalModel", "VideoNet", "build_backbone",
           "build_model", "predict", "seeded_init", "train_model"]
