"""Data sources, splits, preprocessing and the training view handed to families."""

from .dataset import Dataset, Recording, describe, load_dataset
from .preprocess import Preprocessor, delayed_copies, delayed_differences
from .training import Series, TrainingData, training_data

__all__ = [
    "Dataset",
    "Recording",
    "describe",
    "load_dataset",
    "Preprocessor",
    "delayed_copies",
    "delayed_differences",
    "Series",
    "TrainingData",
    "training_data",
]
