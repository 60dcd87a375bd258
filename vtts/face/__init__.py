"""Personalized face models: MIAPs, Animation Definition Tables, temporal tables, the deformation
engine and model loading (Ostermann & Haratsch, sections 3.3 and 4)."""

from vtts.face.adt import (
    Adt,
    AnimationTables,
    MeshTable,
    TransformTable,
    check_tables,
    embed_tables,
    format_adt,
    interval_weights,
    parse_adt,
    read_adt,
    strip_tables,
    tables_from_scene,
    write_adt,
)
from vtts.face.deform import DeformationEngine, Pose
from vtts.face.miap import N_PARAMS, Miap, all_miaps, face_params
from vtts.face.model import FaceModel, bundled_models, find_model, load_model
from vtts.face.temporal import ExpressionTiming, Habit, TemporalTables

__all__ = [
    "N_PARAMS",
    "Adt",
    "AnimationTables",
    "DeformationEngine",
    "ExpressionTiming",
    "FaceModel",
    "Habit",
    "MeshTable",
    "Miap",
    "Pose",
    "TemporalTables",
    "TransformTable",
    "all_miaps",
    "bundled_models",
    "check_tables",
    "embed_tables",
    "face_params",
    "find_model",
    "format_adt",
    "interval_weights",
    "load_model",
    "parse_adt",
    "read_adt",
    "strip_tables",
    "tables_from_scene",
    "write_adt",
]
