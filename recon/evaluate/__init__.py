"""How good a head is: not on the product's path, for tests, benchmarks and notebooks.

- :mod:`~recon.evaluate.synthetic`: ICT FaceKit identities painted and photographed, with
  their true points and shapes (the embedded example is one);
- :mod:`~recon.evaluate.fidelity`: a built head re-projected into its photos (PSNR, SSIM),
  the albedo's error and the seams' figures;
- :mod:`~recon.evaluate.machine`: the processor and library versions a benchmark ran on
  (detected points, and so the figures, differ between processors).
"""
