!> Stable time step of the explicit integrators for the lattice: omega_max from the cell-level
!> (element-by-element) bound, and the largest step for which every damped mode stays stable
!> under RK4 or velocity Verlet.
module iem_stable_dt
  use iem_kinds, only: wp, i8
  use iem_constants, only: rk4_imag_limit
  use iem_spring_constants, only: cell_constants_t
  use iem_cell_kernel, only: cell_force
  implicit none
  private
  public :: cell_stiffness, cell_omega_max, rk4_stable_dt, rk4_amplification, jacobi_eigenvalues
  public :: modal_damping_ratio, capped_beta, cubic_roots, verlet_stable_dt, verlet_mode_radius

contains

  !> Tangent stiffness K(8, 8) of a cell at rest, by central differences of the force kernel.
  pure function cell_stiffness(k) result(kmat)
    type(cell_constants_t), intent(in) :: k
    real(wp) :: kmat(8, 8)
    real(wp) :: u(2, 4), v(2, 4), fp(2, 4), fm(2, 4), e, p, h
    integer :: col
    h = 1.0e-6_wp*min(k%lx, k%ly)
    v = 0.0_wp
    do col = 1, 8
      u = 0.0_wp
      u(mod(col - 1, 2) + 1, (col - 1)/2 + 1) = h
      call cell_force(k, u, v, 0.0_wp, fp, e, p)
      u = -u
      call cell_force(k, u, v, 0.0_wp, fm, e, p)
      kmat(:, col) = reshape(fp - fm, [8])/(2.0_wp*h)
    end do
    kmat = 0.5_wp*(kmat + transpose(kmat))
  end function cell_stiffness

  !> Highest natural frequency (rad/s) of one cell with its lumped corner mass m_corner: an
  !> upper bound of the lattice's omega_max (element-by-element bound).
  pure real(wp) function cell_omega_max(k, m_corner) result(w)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: m_corner
    real(wp) :: ev(8)
    ev = jacobi_eigenvalues(cell_stiffness(k)/m_corner)
    w = sqrt(max(maxval(ev), 0.0_wp))
  end function cell_omega_max

  !> Largest dt for which RK4 is stable for every mode omega in [0, omega_max] under the
  !> damping alpha*M*v + beta*K*w, where w = v, or, with omega_cap > 0, w is v low-pass
  !> filtered at omega_cap (dw/dt = omega_cap (v - w)); 2*sqrt(2)/omega_max when undamped.
  pure real(wp) function rk4_stable_dt(omega_max, alpha, beta, omega_cap) result(dt)
    real(wp), intent(in) :: omega_max, alpha, beta
    real(wp), intent(in), optional :: omega_cap
    integer, parameter :: n_samples = 400
    integer :: s, j
    real(wp) :: w, wc
    complex(wp) :: lam(3)
    wc = 0.0_wp
    if (present(omega_cap)) wc = omega_cap
    if (alpha == 0.0_wp .and. beta == 0.0_wp) then
      dt = rk4_imag_limit/omega_max
      return
    end if
    dt = huge(1.0_wp)
    if (wc > 0.0_wp) dt = ray_limit(cmplx(-wc, 0.0_wp, wp))
    do s = 0, n_samples
      w = omega_max*real(s, wp)/n_samples
      lam = mode_roots(w, alpha, beta, wc)
      do j = 1, 3
        dt = min(dt, ray_limit(lam(j)))
      end do
    end do
  end function rk4_stable_dt

  !> Largest dt for which velocity Verlet (iem_verlet) is stable for every mode omega in
  !> [0, omega_max] under the damping of rk4_stable_dt, the damping force taken at the
  !> half-step velocity; 2/omega_max when undamped.
  pure real(wp) function verlet_stable_dt(omega_max, alpha, beta, omega_cap) result(dt)
    real(wp), intent(in) :: omega_max, alpha, beta
    real(wp), intent(in), optional :: omega_cap
    integer, parameter :: n_samples = 200, n_scan = 100
    real(wp), parameter :: tol = 1.0e-10_wp
    integer :: s, j, it
    real(wp) :: w, wc, lo, hi, h
    wc = 0.0_wp
    if (present(omega_cap)) wc = omega_cap
    if (alpha == 0.0_wp .and. beta == 0.0_wp) then
      dt = 2.0_wp/omega_max
      return
    end if
    dt = 2.0_wp/omega_max
    do s = 1, n_samples
      w = omega_max*real(s, wp)/n_samples
      ! first unstable step on a scan below this mode's undamped limit, then bisection
      ! (lo only grows: once it reaches dt this mode cannot lower dt, and the rest of its scan
      ! or bisection is skipped, which leaves dt exactly as the whole search would)
      lo = 0.0_wp
      hi = -1.0_wp
      do j = 1, n_scan
        h = 2.0_wp/w*real(j, wp)/n_scan
        if (verlet_mode_radius(w, alpha, beta, wc, h) > 1.0_wp + tol) then
          hi = h
          exit
        end if
        lo = h
        if (lo >= dt) exit
      end do
      if (hi < 0.0_wp) cycle
      do it = 1, 50
        if (lo >= dt) exit
        h = 0.5_wp*(lo + hi)
        if (verlet_mode_radius(w, alpha, beta, wc, h) > 1.0_wp + tol) then
          hi = h
        else
          lo = h
        end if
      end do
      dt = min(dt, lo)
    end do
  end function verlet_stable_dt

  !> Spectral radius of one velocity Verlet step of a mode of frequency w under the damping
  !> of rk4_stable_dt: the map of (u, half-step velocity, filtered velocity) over one step.
  pure real(wp) function verlet_mode_radius(w, alpha, beta, wc, dt) result(rho)
    real(wp), intent(in) :: w, alpha, beta, wc, dt
    real(wp) :: m(3, 3), z(3), a, c, c2, c1, c0
    complex(wp) :: lam(3)
    integer :: j
    c = 0.0_wp
    if (wc > 0.0_wp) c = 1.0_wp - exp(-wc*dt)
    do j = 1, 3
      z = 0.0_wp
      z(j) = 1.0_wp
      ! z = (u, q, w): q the velocity of the last half step, w the filter
      if (wc > 0.0_wp) then
        a = -w**2*z(1) - alpha*z(2) - beta*w**2*z(3)
      else
        a = -w**2*z(1) - (alpha + beta*w**2)*z(2)
      end if
      m(2, j) = z(2) + dt*a
      m(1, j) = z(1) + dt*m(2, j)
      m(3, j) = z(3) + c*(m(2, j) - z(3))
      if (wc == 0.0_wp) m(3, j) = 0.0_wp
    end do
    ! characteristic polynomial x^3 + c2 x^2 + c1 x + c0
    c2 = -(m(1, 1) + m(2, 2) + m(3, 3))
    c1 = m(1, 1)*m(2, 2) - m(1, 2)*m(2, 1) + m(1, 1)*m(3, 3) - m(1, 3)*m(3, 1) + &
         m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)
    c0 = -(m(1, 1)*(m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)) - m(1, 2)*(m(2, 1)*m(3, 3) - &
           m(2, 3)*m(3, 1)) + m(1, 3)*(m(2, 1)*m(3, 2) - m(2, 2)*m(3, 1)))
    lam = cubic_roots(c2, c1, c0)
    rho = maxval(abs(lam))
  end function verlet_mode_radius

  !> Eigenvalues of one mode of frequency w under the damping of rk4_stable_dt: the roots of
  !> l^2 + (alpha + beta w^2) l + w^2 (undamped filter, third root 0), or with the filter the
  !> roots of l^3 + (alpha + wc) l^2 + (w^2 (1 + beta wc) + alpha wc) l + w^2 wc.
  pure function mode_roots(w, alpha, beta, wc) result(lam)
    real(wp), intent(in) :: w, alpha, beta, wc
    complex(wp) :: lam(3), disc
    real(wp) :: c
    if (wc > 0.0_wp) then
      lam = cubic_roots(alpha + wc, w**2*(1.0_wp + beta*wc) + alpha*wc, w**2*wc)
    else
      c = alpha + beta*w**2
      disc = sqrt(cmplx(c**2 - 4.0_wp*w**2, 0.0_wp, wp))
      lam = [0.5_wp*(-c + disc), 0.5_wp*(-c - disc), (0.0_wp, 0.0_wp)]
    end if
  end function mode_roots

  !> Damping ratio -Re(l)/|l| of the oscillatory (most weakly damped complex) root of a mode of
  !> frequency w under the damping of rk4_stable_dt.
  pure real(wp) function modal_damping_ratio(w, alpha, beta, wc) result(z)
    real(wp), intent(in) :: w, alpha, beta, wc
    complex(wp) :: lam(3)
    integer :: j
    lam = mode_roots(w, alpha, beta, wc)
    z = 1.0_wp
    do j = 1, 3
      if (abs(aimag(lam(j))) > 1.0e-12_wp*abs(lam(j))) z = min(z, -real(lam(j))/abs(lam(j)))
    end do
  end function modal_damping_ratio

  !> The beta that gives the damping ratio z at frequency w with the filter at wc > 0
  !> (first-order estimate 2 z (wc^2 + w^2) / (w wc^2), refined by bisection on the exact
  !> modal ratio).
  pure real(wp) function capped_beta(z, w, wc) result(beta)
    real(wp), intent(in) :: z, w, wc
    real(wp) :: lo, hi
    integer :: it
    beta = 2.0_wp*z*(wc**2 + w**2)/(w*wc**2)
    lo = 0.0_wp
    hi = 4.0_wp*beta
    do it = 1, 200
      beta = 0.5_wp*(lo + hi)
      if (modal_damping_ratio(w, 0.0_wp, beta, wc) > z) then
        hi = beta
      else
        lo = beta
      end if
    end do
  end function capped_beta

  !> Roots of the monic cubic x^3 + a2 x^2 + a1 x + a0: those of 500 sweeps of the
  !> Durand-Kerner iteration, found in fewer once the sweeps repeat bit for bit with period
  !> 1 or 2 (the rest of the 500 would only repeat them).
  pure function cubic_roots(a2, a1, a0) result(x)
    real(wp), intent(in) :: a2, a1, a0
    integer, parameter :: n_sweeps = 500
    complex(wp) :: x(3), p, q, x1(3), x2(3)
    real(wp) :: radius
    integer :: it, i, j
    radius = 1.0_wp + max(abs(a2), abs(a1)**(1.0_wp/2.0_wp), abs(a0)**(1.0_wp/3.0_wp))
    x = radius*[(0.4_wp, 0.9_wp), (-0.7_wp, 0.3_wp), (0.2_wp, -0.8_wp)]
    ! x1, x2: the roots one and two sweeps before
    x1 = x
    x2 = x
    do it = 1, n_sweeps
      do i = 1, 3
        p = ((x(i) + a2)*x(i) + a1)*x(i) + a0
        q = (1.0_wp, 0.0_wp)
        do j = 1, 3
          if (j /= i) q = q*(x(i) - x(j))
        end do
        ! (q /= 0 without the modulus: the same test for finite q, a hypot less a root)
        if (real(q) /= 0.0_wp .or. aimag(q) /= 0.0_wp) x(i) = x(i) - p/q
      end do
      ! (the same bits, a zero's sign too: a sweep is a function of the bits it starts from)
      if (same_bits(x, x1)) exit
      if (it > 1 .and. same_bits(x, x2)) then
        ! period 2: sweep n_sweeps gives x when an even number of sweeps is left, else x1
        if (mod(n_sweeps - it, 2) /= 0) x = x1
        exit
      end if
      x2 = x1
      x1 = x
    end do
  contains
    !> Whether a and b hold the same bits (value by value: no temporary arrays).
    pure logical function same_bits(a, b)
      complex(wp), intent(in) :: a(3), b(3)
      integer :: k
      same_bits = .false.
      do k = 1, 3
        if (transfer(real(a(k)), 0_i8) /= transfer(real(b(k)), 0_i8)) return
        if (transfer(aimag(a(k)), 0_i8) /= transfer(aimag(b(k)), 0_i8)) return
      end do
      same_bits = .true.
    end function same_bits
  end function cubic_roots

  !> RK4 amplification factor R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24.
  pure complex(wp) function rk4_amplification(z) result(r)
    complex(wp), intent(in) :: z
    r = 1.0_wp + z*(1.0_wp + z*(0.5_wp + z*(1.0_wp/6.0_wp + z/24.0_wp)))
  end function rk4_amplification

  !> Largest h with |R(h*lam)| <= 1 on [0, h] (huge for lam = 0).
  pure real(wp) function ray_limit(lam) result(h)
    complex(wp), intent(in) :: lam
    real(wp) :: r, lo, hi, step
    integer :: it
    if (abs(lam) == 0.0_wp) then
      h = huge(1.0_wp)
      return
    end if
    step = 1.0e-3_wp
    r = 0.0_wp
    do while (r < 4.0_wp)
      if (abs(rk4_amplification((r + step)*lam/abs(lam))) > 1.0_wp + 1.0e-13_wp) exit
      r = r + step
    end do
    lo = r
    hi = r + step
    do it = 1, 60
      r = 0.5_wp*(lo + hi)
      if (abs(rk4_amplification(r*lam/abs(lam))) > 1.0_wp + 1.0e-13_wp) then
        hi = r
      else
        lo = r
      end if
    end do
    h = lo/abs(lam)
  end function ray_limit

  !> Eigenvalues of a small symmetric matrix by cyclic Jacobi rotations.
  pure function jacobi_eigenvalues(a_in) result(ev)
    real(wp), intent(in) :: a_in(:, :)
    real(wp) :: ev(size(a_in, 1))
    real(wp) :: a(size(a_in, 1), size(a_in, 1)), off, theta, t, c, s, tau, apq, scale
    real(wp) :: akp, akq
    integer :: n, p, q, k, sweep
    a = a_in
    n = size(a, 1)
    scale = max(maxval(abs(a)), tiny(1.0_wp))
    do sweep = 1, 100
      off = 0.0_wp
      do p = 1, n - 1
        do q = p + 1, n
          off = off + a(p, q)**2
        end do
      end do
      if (sqrt(off) <= 1.0e-15_wp*scale) exit
      do p = 1, n - 1
        do q = p + 1, n
          apq = a(p, q)
          if (abs(apq) <= 1.0e-300_wp) cycle
          theta = (a(q, q) - a(p, p))/(2.0_wp*apq)
          t = sign(1.0_wp, theta)/(abs(theta) + sqrt(theta**2 + 1.0_wp))
          c = 1.0_wp/sqrt(t**2 + 1.0_wp)
          s = t*c
          tau = s/(1.0_wp + c)
          a(p, p) = a(p, p) - t*apq
          a(q, q) = a(q, q) + t*apq
          a(p, q) = 0.0_wp
          a(q, p) = 0.0_wp
          do k = 1, n
            if (k == p .or. k == q) cycle
            akp = a(k, p)
            akq = a(k, q)
            a(k, p) = akp - s*(akq + tau*akp)
            a(p, k) = a(k, p)
            a(k, q) = akq + s*(akp - tau*akq)
            a(q, k) = a(k, q)
          end do
        end do
      end do
    end do
    do k = 1, n
      ev(k) = a(k, k)
    end do
  end function jacobi_eigenvalues
end module iem_stable_dt
