"""tests/depth: nothing is downloaded from Hugging Face (HF_HUB_OFFLINE=1 before huggingface_hub is read),
and the tiny randomly initialised transformers models the Hugging Face tests load are built once."""

from __future__ import annotations

import json
import os

import pytest

os.environ["HF_HUB_OFFLINE"] = "1"


@pytest.fixture(autouse=True)
def hf_offline(monkeypatch):
    """Offline even if huggingface_hub was imported (and read its environment) before this conftest."""
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    try:
        from huggingface_hub import constants
    except ImportError:
        return
    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", True)


def _dinov2(layers: int = 2):
    from transformers import Dinov2Config

    return Dinov2Config(
        hidden_size=16, num_hidden_layers=layers, num_attention_heads=2, intermediate_size=32, patch_size=14,
        image_size=56, out_features=[f"stage{i + 1}" for i in range(layers)], reshape_hidden_states=False,
    )  # fmt: skip


def _save(root, name, config, processor) -> str:
    import torch
    from transformers import AutoModelForDepthEstimation

    torch.manual_seed(0)
    folder = root / name
    model = AutoModelForDepthEstimation.from_config(config)
    if name == "depth_pro":  # a plausible field of view (degrees) from the random field-of-view head
        with torch.no_grad():
            model.fov_model.head.layers[2].weight.mul_(0.01)
            model.fov_model.head.layers[2].bias.fill_(60.0)
    model.save_pretrained(folder)
    if isinstance(processor, dict):  # written as save_pretrained writes it (the class needs torchvision)
        (folder / "preprocessor_config.json").write_text(json.dumps(processor))
    else:
        processor.save_pretrained(folder)
    return str(folder)


@pytest.fixture(scope="session")
def hf_models(tmp_path_factory) -> dict[str, str]:
    """Folders of tiny random depth models (each < 300 kB), saved with save_pretrained and their image
    processor: da_relative, da_metric (Depth Anything V2 style, DINOv2 backbone), dpt, glpn, zoedepth,
    depth_pro (with its field-of-view head); plus "bert": a non-depth model folder."""
    pytest.importorskip("transformers")
    from transformers import (
        BertConfig,
        BertModel,
        DepthAnythingConfig,
        DepthProConfig,
        Dinov2Config,
        DPTConfig,
        DPTImageProcessorPil,
        GLPNConfig,
        GLPNImageProcessorPil,
        ZoeDepthConfig,
        ZoeDepthImageProcessorPil,
    )

    root = tmp_path_factory.mktemp("hf")
    da_processor = DPTImageProcessorPil(
        size={"height": 56, "width": 56}, keep_aspect_ratio=True, ensure_multiple_of=14
    )
    out = {}
    for typ in ("relative", "metric"):
        cfg = DepthAnythingConfig(
            backbone_config=_dinov2(), reassemble_hidden_size=16, neck_hidden_sizes=[8, 16],
            reassemble_factors=[2, 1], fusion_hidden_size=8, head_hidden_size=8, depth_estimation_type=typ,
            max_depth=20 if typ == "metric" else 1,
        )  # fmt: skip
        out[f"da_{typ}"] = _save(root, f"da_{typ}", cfg, da_processor)
    cfg = DPTConfig(
        hidden_size=16, num_hidden_layers=2, num_attention_heads=2, intermediate_size=32, image_size=32,
        patch_size=8, backbone_out_indices=[0, 1], neck_hidden_sizes=[8, 16], reassemble_factors=[2, 1],
        fusion_hidden_size=8,
    )  # fmt: skip
    out["dpt"] = _save(root, "dpt", cfg, DPTImageProcessorPil(size={"height": 32, "width": 32}))
    cfg = GLPNConfig(
        num_encoder_blocks=2, depths=[1, 1], sr_ratios=[2, 1], hidden_sizes=[8, 16], patch_sizes=[7, 3],
        strides=[4, 2], num_attention_heads=[1, 1], mlp_ratios=[2, 2], decoder_hidden_size=8, max_depth=10,
    )  # fmt: skip
    out["glpn"] = _save(root, "glpn", cfg, GLPNImageProcessorPil(size_divisor=32))
    cfg = ZoeDepthConfig(
        backbone_config=_dinov2(4), reassemble_factors=[4, 2, 1, 0.5], neck_hidden_sizes=[8, 8, 16, 16],
        fusion_hidden_size=8, num_relative_features=8, bottleneck_features=8, num_attractors=[4, 2, 2, 1],
        bin_embedding_dim=8, bin_configurations=[{"n_bins": 8, "min_depth": 0.1, "max_depth": 10.0}],
        num_patch_transformer_layers=1, patch_transformer_hidden_size=8,
        patch_transformer_intermediate_size=16, patch_transformer_num_attention_heads=1,
    )  # fmt: skip
    zoe_processor = ZoeDepthImageProcessorPil(
        size={"height": 56, "width": 56}, keep_aspect_ratio=True, ensure_multiple_of=14
    )
    out["zoedepth"] = _save(root, "zoedepth", cfg, zoe_processor)
    vit = dict(hidden_size=16, num_hidden_layers=2, num_attention_heads=2, intermediate_size=32, patch_size=8,
               image_size=32)  # fmt: skip
    cfg = DepthProConfig(
        fusion_hidden_size=8, patch_size=32, intermediate_hook_ids=[1, 0], intermediate_feature_dims=[8, 8],
        scaled_images_ratios=[0.5, 1], scaled_images_overlap_ratios=[0.0, 0.25],
        scaled_images_feature_dims=[8, 8], use_fov_model=True, num_fov_head_layers=1,
        image_model_config=Dinov2Config(**vit), patch_model_config=Dinov2Config(**vit),
        fov_model_config=Dinov2Config(**vit),
    )  # fmt: skip
    out["depth_pro"] = _save(root, "depth_pro", cfg, {
        "image_processor_type": "DepthProImageProcessor", "size": {"height": 64, "width": 64},
        "do_resize": True, "do_rescale": True, "rescale_factor": 1 / 255, "do_normalize": True,
        "image_mean": [0.5, 0.5, 0.5], "image_std": [0.5, 0.5, 0.5], "resample": 2,
    })  # fmt: skip
    bert = root / "bert"
    BertModel(BertConfig(hidden_size=8, num_hidden_layers=1, num_attention_heads=1, intermediate_size=8,
                         vocab_size=50)).save_pretrained(bert)  # fmt: skip
    out["bert"] = str(bert)
    return out
